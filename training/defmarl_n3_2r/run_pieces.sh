#!/usr/bin/env bash
# DEF-MARL (n3) for the disc convention (collision at 0.2 m: workflow/configs/reading_2r.yaml, issue 38
# reading (b)), from scratch at the shipped budget, in resumable pieces of at most ~20 minutes; state.pt
# beside this script is committed, so any machine resumes where the last piece stopped.
exec "$(dirname "$0")/../run_pieces.sh" train-defmarl --config config.yaml workflow/configs/reading_2r.yaml --variant n3 \
    --out training/defmarl_n3_2r/defmarl_n3.pt --checkpoint training/defmarl_n3_2r/state.pt \
    --time-limit 1140 --no-track --no-progress --threads 1
