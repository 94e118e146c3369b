#!/usr/bin/env bash
# Train V̂ on the 0.3 s horizon (workflow/configs/vhat_horizon_0.3.yaml, issue 33) in resumable 20-minute
# pieces; the checkpoint beside this script is committed, so any machine resumes where the last piece stopped.
exec "$(dirname "$0")/../run_pieces.sh" train-value --config config.yaml workflow/configs/vhat_horizon_0.3.yaml --kind vhat \
    --out training/vhat_h03/vhat.pt --checkpoint training/vhat_h03/vhat.ckpt.pt --time-limit 1200 --no-track --no-progress --threads 1
