#!/usr/bin/env bash
# Issue 60 item 3, training variance and the recipe: the shipped V̂'s recipe trained from scratch with
# training seeds 1 and 2 (value_functions.vhat_variants.s1 / s2); the base recipe with uniform states
# (vhat_variants.nocs, issue 61 item 4: the recipe re-chosen on validation seeds,
# docs/findings/2026-11-29-vhat-recipe-preregistered.md); the shipped recipe itself again with its own
# seed 0 (does the workflow reproduce models/vhat.pt?); then the 4x-batch uniform constant-rate V̂
# (vhat_variants.bs16k); then the recipe deployed since issue 61 (uniform states) with training seeds 1 and 2
# (vhat_variants.us1 / us2: the training-seed spread of the V̂ the protocol now ships). One after another, each in resumable pieces (exit 75 = paused); the
# checkpoints under training/vhat_<name>/ are committed, so any machine resumes where the last piece
# stopped (the batch of iteration k is a function of (seed, k)). One torch thread, as the shipped V̂ was
# trained (models/manifest.json: "cpu, 1 torch thread"). Usage (repository root):
#   NICE=0 training/vhat_seeds/run_pieces.sh          # all five in turn
#   training/vhat_seeds/run_pieces.sh s2               # one of them
set -u
cd "$(dirname "$0")/../.."
common=(--config config.yaml --kind vhat --time-limit "${PIECE_S:-1200}" --no-track --no-progress --threads "${THREADS:-1}")
train() {   # name variant...
  local name=$1; shift
  mkdir -p "training/vhat_$name"
  [ -f "training/vhat_$name/vhat.pt" ] && { echo "vhat_$name: finished"; return 0; }
  training/run_pieces.sh train-value "${common[@]}" "$@" --out "training/vhat_$name/vhat.pt" \
      --checkpoint "training/vhat_$name/vhat.ckpt.pt"
}
for name in ${@:-s1 s2 nocs s0 bs16k us1 us2}; do
  case $name in
    s0) train s0 --variant cs ;;             # the cs recipe (shipped until issue 61), its own seed: models/vhat_cs.pt again?
    s1|s2|nocs|bs16k|us1|us2) train "$name" --variant "$name" ;;
    *) echo "unknown run '$name' (s0 s1 s2 nocs bs16k us1 us2)" >&2; exit 2 ;;
  esac || exit $?
done
