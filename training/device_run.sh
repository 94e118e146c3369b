#!/usr/bin/env bash
# One device-machine call (GPU + 16 cores): advance every resumable training of this wave in parallel
# for LIMIT seconds, then pack training/ into $OUT/training.tgz. Each piece resumes from the committed
# checkpoint and stops with exit 75 (checkpoint kept) when LIMIT is reached. The V̂ trainings use the
# GPU (config device: auto); DEF-MARL stays on the CPU (its rollouts are small). Usage (repo root):
#   LIMIT=400 bash training/device_run.sh
set -u
LIMIT=${LIMIT:-400}
PY=${PYTHON:-python3}
export PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH} PYTHONUNBUFFERED=1
mkdir -p /tmp/devlogs; echo "device: cpu" > /tmp/device_cpu.yaml
common=(--time-limit "$LIMIT" --no-track --no-progress --threads 2)
pids=()
run() { local name=$1; shift; ( $PY -m madpinn "$@" "${common[@]}" > "/tmp/devlogs/$name.log" 2>&1; echo "$name exit $?" >> "/tmp/devlogs/$name.log" ) & pids+=($!); }
run vhat_h04 train-value --config config.yaml workflow/configs/vhat_horizon_0.4.yaml --kind vhat \
    --out training/vhat_h04/vhat.pt --checkpoint training/vhat_h04/vhat.ckpt.pt
run vhat_h03 train-value --config config.yaml workflow/configs/vhat_horizon_0.3.yaml --kind vhat \
    --out training/vhat_h03/vhat.pt --checkpoint training/vhat_h03/vhat.ckpt.pt
run vhat_speed train-value --config config.yaml workflow/configs/vhat_speed_aware.yaml --kind vhat \
    --model init=models/vhat.pt --out training/vhat_speed/vhat.pt --checkpoint training/vhat_speed/vhat.ckpt.pt
run defmarl_att train-defmarl --config config.yaml workflow/configs/defmarl_attention.yaml /tmp/device_cpu.yaml --variant n8 \
    --out training/defmarl_n8_attention/defmarl_n8.pt --checkpoint training/defmarl_n8_attention/state.pt
( while sleep 60; do nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader 2>/dev/null; done ) &
monitor=$!
wait "${pids[@]}"; kill $monitor 2>/dev/null
for f in /tmp/devlogs/*.log; do echo "== $f"; tail -n 5 "$f"; done
mkdir -p "${OUT:-/tmp/out}"; cp /tmp/devlogs/*.log "${OUT:-/tmp/out}/" 2>/dev/null
tar czf "${OUT:-/tmp/out}/training.tgz" training/
ls -la "${OUT:-/tmp/out}"
