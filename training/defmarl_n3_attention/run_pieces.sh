#!/usr/bin/env bash
# DEF-MARL (n3) with the attention encoder from scratch (workflow/configs/defmarl_attention.yaml), resumable
# pieces; state.pt beside this script is committed.
exec "$(dirname "$0")/../run_pieces.sh" train-defmarl --config config.yaml workflow/configs/defmarl_attention.yaml --variant n3 \
    --out training/defmarl_n3_attention/defmarl_n3.pt --checkpoint training/defmarl_n3_attention/state.pt \
    --time-limit 1140 --no-track --no-progress --threads 1
