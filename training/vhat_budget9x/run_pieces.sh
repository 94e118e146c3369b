#!/usr/bin/env bash
# Issue 46: V̂ from scratch at 9x the shipped sample budget, constant lr 2e-5 (workflow/configs/vhat_budget_9x.yaml),
# in resumable 20-minute pieces; the checkpoint beside this script is committed, so any machine resumes where the
# last piece stopped (same weights as an uninterrupted run on the same device and thread count: the batch of
# iteration k is a function of (seed, k)). THREADS=2 on an otherwise idle 2-core machine: 52 ms/iteration
# against 90 with one thread (training/vhat_budget9x/pieces.md).
exec "$(dirname "$0")/../run_pieces.sh" train-value --config config.yaml workflow/configs/vhat_budget_9x.yaml --kind vhat \
    --out training/vhat_budget9x/vhat.pt --checkpoint training/vhat_budget9x/vhat.ckpt.pt --time-limit 1200 --no-track --no-progress --threads "${THREADS:-1}"
