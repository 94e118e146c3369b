#!/usr/bin/env bash
# One GPU piece of the 9x V̂ (issue 46) on a lent device machine (`run` tool; its image has torch, numpy,
# pandas, pyyaml, matplotlib, tqdm, but not jsonschema, which the config loader needs: download its
# wheels here once, into the git-excluded .whl/, and name `.whl` in the run's carry:
#   python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
#     --platform manylinux_2_17_x86_64 -d .whl jsonschema==4.26.0 jsonschema-specifications==2025.9.1 \
#     referencing==0.37.0 rpds-py==2026.9.1
# ). Resumes the committed checkpoint, trains for BUDGET_S
# seconds on CUDA (config device: auto), keeps the 6x snapshot (iteration 360 000) if the piece passes it,
# and copies the checkpoint (and the finished model, if any) to $OUT. Usage on the device:
#   BUDGET_S=420 bash training/vhat_budget9x/gpu_piece.sh
# Weights trained on CUDA differ from CPU-trained ones in float rounding only; the pieces' devices are
# recorded in training/vhat_budget9x/pieces.md.
set -u
cd "$(dirname "$0")/../.."
py=${PYTHON:-python3}
if [ -d .whl ]; then "$py" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target /tmp/site .whl/*.whl || exit; fi
export PYTHONPATH=$PWD:/tmp/site PYTHONUNBUFFERED=1
out=${OUT:?set OUT to a folder for the results}
ck=${CHECKPOINT:-training/vhat_budget9x/vhat.ckpt.pt}
snap_at=${SNAP_AT:-360000}   # the 6x snapshot (value_functions.vhat_variants.b6x.stop_at)
t_end=$(( $(date +%s) + ${BUDGET_S:?seconds of training} ))
iter() { "$py" -c "import sys; from madpinn.value_functions.model import read_checkpoint; print(int(read_checkpoint(sys.argv[1], 'vhat')['meta']['train_state']['iteration']))" "$1"; }
train() { "$py" -m madpinn train-value --config config.yaml workflow/configs/vhat_budget_9x.yaml --kind vhat \
    --out "$out/vhat_b9x.pt" --checkpoint "$ck" --no-track --no-progress --time-limit "$1" "${@:2}"
  local rc=$?; [ $rc -eq 0 ] || [ $rc -eq 75 ] || exit $rc; }   # 75: paused at the time limit, checkpoint kept
"$py" -c "import torch; print('torch', torch.__version__, 'cuda', torch.cuda.is_available(), torch.cuda.get_device_name(0) if torch.cuda.is_available() else '')"
start=$(iter "$ck"); echo "start iteration $start"; t0=$(date +%s)
if [ "$start" -lt $snap_at ]; then
  train $(( t_end - $(date +%s) )) --stop-after $(( snap_at - start ))
  now=$(iter "$ck")
  if [ "$now" -eq $snap_at ]; then cp "$ck" "$out/vhat_it$(printf %06d $snap_at).ckpt.pt"; echo "kept the 6x snapshot"; fi
fi
left=$(( t_end - $(date +%s) ))
if [ "$left" -gt 10 ] && [ -f "$ck" ] && [ "$(iter "$ck")" -ge $snap_at ]; then train "$left"; fi
[ -f "$ck" ] && cp "$ck" "$out/vhat.ckpt.pt" && end=$(iter "$ck") || end=done
echo "end iteration $end after $(( $(date +%s) - t0 )) s (from $start)"
