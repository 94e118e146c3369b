#!/usr/bin/env bash
# Train V̂ on the 0.4 s horizon (workflow/configs/vhat_horizon_0.4.yaml, issue 33) in resumable 20-minute
# pieces; the checkpoint beside this script is committed, so any machine resumes where the last piece stopped.
exec "$(dirname "$0")/../run_pieces.sh" train-value --config config.yaml workflow/configs/vhat_horizon_0.4.yaml --kind vhat \
    --out training/vhat_h04/vhat.pt --checkpoint training/vhat_h04/vhat.ckpt.pt --time-limit 1200 --no-track --no-progress --threads 1
