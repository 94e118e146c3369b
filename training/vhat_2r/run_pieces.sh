#!/usr/bin/env bash
# Train vhat for the disc convention (collision at 0.2 m; workflow/configs/reading_2r.yaml, issue 38 reading (b))
# in resumable 20-minute pieces; the checkpoint beside this script is committed, so any machine resumes.
exec "$(dirname "$0")/../run_pieces.sh" train-value --config config.yaml workflow/configs/reading_2r.yaml --kind vhat \
    --out training/vhat_2r/vhat.pt --checkpoint training/vhat_2r/vhat.ckpt.pt --time-limit 1200 --no-track --no-progress --threads 1
