#!/usr/bin/env bash
# Run the cells of a validation-seed overlay in batches and keep each batch: after every batch the
# run's new cells are published into the overlay's committed cache (validation_cache/, see its
# README) and, with COMMIT=1, committed, so a session stopped mid-queue loses at most the batch in
# flight. A later run of the same command restores what was kept and computes the rest. Pages
# (tables, figures) are published only with FIGURES_TO=<dir> (paper_figures for an overlay with its
# own results directory), never by default.
#
#   scripts/validation_cells.sh OVERLAY BATCH_SIZE TARGET...
#   COMMIT=1 scripts/validation_cells.sh workflow/configs/scenario_laws.yaml 3 \
#       results/scenario_laws/eval/mujoco/grid_uniform/madpinn-wide/n{64,128,256}_seed100.parquet
#
# One job at a time (-j1: the other core is for a training); JOBS=2 for both cores. The protocol's own
# cells the same way, kept in output_cache/ (its overlay: the shipped one):
#   CACHE=output_cache COMMIT=1 scripts/validation_cells.sh workflow/configs/shipped.yaml 4 TARGET...
# and Table II's final readings on seed 0, whose page is published apart:
#   CACHE=output_cache COMMIT=1 FIGURES_TO=paper_figures/table_ii_final scripts/validation_cells.sh workflow/configs/table_ii_final.yaml 3 TARGET...
set -u
cd "$(dirname "$0")/.."
[ $# -ge 3 ] || { echo "usage: $0 OVERLAY BATCH_SIZE TARGET..." >&2; exit 2; }
overlay=$1 batch=$2; shift 2
[ -f "$overlay" ] || { echo "no overlay '$overlay'" >&2; exit 2; }
configs=(config.yaml workflow/configs/shipped.yaml "$overlay")
py=${PYTHON:-.venv/bin/python}
targets=("$@")
for ((i = 0; i < ${#targets[@]}; i += batch)); do
  part=("${targets[@]:i:batch}")
  echo "== batch $((i / batch + 1)): ${part[*]}"
  "$py" -m snakemake -j"${JOBS:-1}" --keep-going --configfile "${configs[@]}" --profile profiles/shipped -- "${part[@]}"
  rc=$?
  # the batch's cells go into the committed cache; the overlay's pages only where FIGURES_TO names (e.g.
  # paper_figures/conformal's overlay: FIGURES_TO=paper_figures; the final readings: paper_figures/table_ii_final).
  # Without it they go to a scratch directory: an overlay whose results are the protocol's (results/) would
  # otherwise copy this machine's restore outputs (its own neighbour timing, figures) over paper_figures/.
  scratch=$(mktemp -d)
  "$py" -m madpinn publish --config "${configs[@]}" --figures-to "${FIGURES_TO:-$scratch}" || exit $?
  rm -rf "$scratch"
  cache=${CACHE:-validation_cache}   # where the overlay keeps its cells (its paths.output_cache)
  if [ "${COMMIT:-0}" = 1 ] && [ -n "$(git status --porcelain --ignored -- "$cache")" ]; then
    # a commit made beside this one (a training's checkpoint) may hold git's index lock for a moment: retry
    for try in 1 2 3 4 5 6; do
      git add -f "$cache" && git commit -q -m "${cache%_cache} cells: ${part[*]}" -- "$cache" && break
      [ $try -lt 6 ] || exit 1
      sleep 5
    done
  fi
  [ $rc -eq 0 ] || exit $rc
done
