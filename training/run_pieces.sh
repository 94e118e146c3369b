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
# Under the kernel's autogroup scheduler (sched_autogroup_enabled = 1) nice acts only inside one session:
# a script started with setsid is a session of its own and would take a full share of the CPU beside the
# cells whatever its nice. Started so (its own session leader), it lowers its session's autogroup too.
if [ "$(ps -o sid= -p $$ | tr -d ' ')" = "$$" ] && [ -w /proc/self/autogroup ]; then
  echo "$niceness" > /proc/self/autogroup 2>/dev/null || true
fi
while :; do
  nice -n "$niceness" "$py" -m madpinn "$@"
  rc=$?
  [ $rc -eq 75 ] || exit $rc
done
