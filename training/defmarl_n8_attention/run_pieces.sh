#!/usr/bin/env bash
# Train DEF-MARL (n8) from scratch with the attention encoder (workflow/configs/defmarl_attention.yaml)
# in resumable pieces of at most ~20 minutes (--time-limit 1140 s + the iteration and validation in
# flight); the state beside this script (state.pt) is committed, so any machine resumes where the last
# piece stopped. Curve: defmarl_n8_history.csv here; model defmarl_n8.pt when the 1 100 iterations are
# done. Exit 0 when finished, otherwise the failing piece's code. CPU-friendly: nice 19, one thread.
set -u
cd "$(dirname "$0")/../.."
py=${PYTHON:-.venv/bin/python}
while :; do
  nice -n 19 $py -m madpinn train-defmarl --config config.yaml workflow/configs/defmarl_attention.yaml --variant n8 \
      --out training/defmarl_n8_attention/defmarl_n8.pt --checkpoint training/defmarl_n8_attention/state.pt \
      --time-limit 1140 --no-track --no-progress --threads 1
  rc=$?
  [ $rc -eq 75 ] || exit $rc
done
