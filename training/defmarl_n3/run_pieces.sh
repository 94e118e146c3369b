#!/usr/bin/env bash
# Train DEF-MARL (n3) on from the shipped models/defmarl_n3.pt (workflow/configs/defmarl_continue.yaml) in
# resumable pieces of at most ~20 minutes (--time-limit 1140 s + the iteration and validation in flight);
# state.pt beside this script is committed, so any machine resumes where the last piece stopped (--init
# is only read while there is no state.pt). The curve (training and validation columns) is
# defmarl_n3_history.csv here; the finished model defmarl_n3.pt (plateau or cap).
exec "$(dirname "$0")/../run_pieces.sh" train-defmarl --config config.yaml workflow/configs/defmarl_continue.yaml --variant n3 \
    --out training/defmarl_n3/defmarl_n3.pt --checkpoint training/defmarl_n3/state.pt --init models/defmarl_n3.pt \
    --time-limit 1140 --no-track --no-progress --threads 1
