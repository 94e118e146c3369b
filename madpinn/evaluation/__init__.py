"""Evaluation: metrics (SPEC §3), evaluation jobs, tables."""
