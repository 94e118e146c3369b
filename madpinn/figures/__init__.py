"""Paper figures, drawn from result files (never from MLflow)."""
