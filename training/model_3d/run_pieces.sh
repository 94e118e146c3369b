#!/usr/bin/env bash
# Issue 63 item 2: V̂ and V_s for the 3-D double integrator at the real budget (the base recipes of
# config.yaml: V̂ 30 000 + 30 000 fine-tune iterations, V_s 15 000 + 6 000), as the variants
# value_functions.vhat_variants.3d / vs_variants.3d of workflow/configs/agent_models.yaml, one after
# another, each in resumable pieces of PIECE_S seconds (exit 75 = paused, checkpoint kept). The
# checkpoints under training/vhat_3d/ and training/vs_3d/ are committed, so any machine resumes where
# the last piece stopped (the batch of iteration k is a function of (seed, k)). One torch thread, as
# the shipped V̂ was trained; device `auto` (config.yaml): the GPU where there is one. Usage (repo root):
#   NICE=0 training/model_3d/run_pieces.sh            # V̂ then V_s
#   training/model_3d/run_pieces.sh vs                 # one of them
#   PIECE_S=300 THREADS=1 EXTRA_CONFIG=more.yaml ...  # piece length (s), torch threads, one more config overlay
# When a model is finished (training/<kind>_3d/<kind>.pt), ship it as models/<kind>_3d.pt
# (python -m madpinn ship-models --model <kind>_3d=training/<kind>_3d/<kind>.pt --config config.yaml
# workflow/configs/agent_models.yaml) and add <kind>_3d to the overlay's shipped_models.names (not
# shipped.yaml's: the 3-D variants exist in that overlay only); the workflow then installs it.
set -u
cd "$(dirname "$0")/../.."
common=(--config config.yaml workflow/configs/agent_models.yaml ${EXTRA_CONFIG:-} --variant 3d
        --time-limit "${PIECE_S:-1200}" --no-track --no-progress --threads "${THREADS:-1}")
train() {   # kind
  local kind=$1 dir="training/$1_3d"
  mkdir -p "$dir"
  [ -f "$dir/$kind.pt" ] && { echo "${kind}_3d: finished ($dir/$kind.pt)"; return 0; }
  training/run_pieces.sh train-value "${common[@]}" --kind "$kind" --out "$dir/$kind.pt" --checkpoint "$dir/$kind.ckpt.pt"
}
for kind in ${@:-vhat vs}; do
  case $kind in
    vhat|vs) train "$kind" ;;
    *) echo "unknown model '$kind' (vhat vs)" >&2; exit 2 ;;
  esac || exit $?
done
