#!/usr/bin/env bash
# Train V̂ on the 0.4 s horizon (workflow/configs/vhat_horizon_0.4.yaml) in resumable 20-minute pieces;
# the checkpoint beside this script is committed, so any machine resumes where the last piece stopped.
set -u
cd "$(dirname "$0")/../.."
py=${PYTHON:-.venv/bin/python}
while :; do
  $py -m madpinn train-value --config config.yaml workflow/configs/vhat_horizon_0.4.yaml --kind vhat \
      --out training/vhat_h04/vhat.pt --checkpoint training/vhat_h04/vhat.ckpt.pt \
      --time-limit 1200 --no-track --no-progress --threads 1
  rc=$?
  [ $rc -eq 75 ] || exit $rc
done
