#!/usr/bin/env bash
# Issue 46: V̂ from scratch at 3x the shipped sample budget, constant lr 2e-5 (workflow/configs/vhat_budget_3x.yaml),
# in resumable 20-minute pieces; the checkpoint beside this script is committed, so any machine resumes where the
# last piece stopped (same weights as an uninterrupted run: the batch of iteration k is a function of (seed, k)).
exec "$(dirname "$0")/../run_pieces.sh" train-value --config config.yaml workflow/configs/vhat_budget_3x.yaml --kind vhat \
    --out training/vhat_budget3x/vhat.pt --checkpoint training/vhat_budget3x/vhat.ckpt.pt --time-limit 1200 --no-track --no-progress --threads 1
