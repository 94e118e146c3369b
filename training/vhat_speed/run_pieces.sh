#!/usr/bin/env bash
# Speed-aware fine-tune of the shipped V̂ (workflow/configs/vhat_speed_aware.yaml, issue 33) in resumable
# 20-minute pieces; the checkpoint beside this script is committed, so any machine resumes where the last piece stopped.
exec "$(dirname "$0")/../run_pieces.sh" train-value --config config.yaml workflow/configs/vhat_speed_aware.yaml --kind vhat \
    --model init=models/vhat.pt --out training/vhat_speed/vhat.pt --checkpoint training/vhat_speed/vhat.ckpt.pt \
    --time-limit 1200 --no-track --no-progress --threads 1
