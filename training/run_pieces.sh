#!/usr/bin/env bash
# Run one resumable training command (train-value / train-defmarl with --time-limit and a committed
# --checkpoint) piece after piece from the repository root until it finishes: exit 75 means "paused,
# checkpoint kept, run me again"; 0 = finished; anything else = the failing piece's code.
# CPU-friendly: nice 19 (NICE=0 to run at normal priority), the command's own --threads. Usage: training/run_pieces.sh ARGS...
# (the arguments of `python -m madpinn`, e.g. train-value --config ... --time-limit 1200 ...).
set -u
cd "$(dirname "$0")/.."
py=${PYTHON:-.venv/bin/python}
niceness=${NICE:-19}
while :; do
  nice -n "$niceness" "$py" -m madpinn "$@"
  rc=$?
  [ $rc -eq 75 ] || exit $rc
done
