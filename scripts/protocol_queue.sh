#!/usr/bin/env bash
# The protocol's cells as a resumable queue, for a rerun that spans sessions: a dry run of `all`
# lists every evaluation cell, oracle bound and V̂ calibration (the shipped profile's cached rules) the
# protocol still lacks in results/, ordered by study (the calibration, which the level rows read, then
# Table I, the large-arena frontier, then the oracle bounds), and scripts/validation_cells.sh runs them in batches, keeping each
# finished batch in output_cache/ (COMMIT=1: committed). A fresh checkout restores what is kept
# in seconds per batch and computes the rest. Afterwards `snakemake … all` builds the tables.
#
#   scripts/protocol_queue.sh [BATCH_SIZE]          # JOBS=2 for both cores (default 1)
#   COMMIT=1 JOBS=2 setsid nohup scripts/protocol_queue.sh 4 > /tmp/protocol_cells.log 2>&1 &
#   LIST=1 scripts/protocol_queue.sh                # print the ordered targets, run nothing
set -u
cd "$(dirname "$0")/.."
py=${PYTHON:-.venv/bin/python}
order=(calibration main ablation_neighbours ablation_update conflict_pairs conflict_lines conflict_circle
       conflict_crossing scaling large_arena_frontier oracle)   # any other study follows, by name
plan=$("$py" -m snakemake -n --nolock --configfile config.yaml workflow/configs/shipped.yaml \
         --profile profiles/shipped all 2>&1) || { echo "$plan" | tail -20 >&2; exit 2; }
# each cell's first output, <results>/eval/<backend>/<study>/<run>/n<N>_seed<S>.parquet (paths.results,
# sim.backend), each oracle bound's, <results>/oracle/<arena>[/<pattern>]/n<N>_seed<S>_s<K>.parquet, and
# each calibration's, <results>/validation/<vhat>_calibration.json, as "<study> <path>" (study "oracle"
# for the bounds, "calibration" for the calibrations)
cells=$(grep -E '^    output: .*/(eval/[^/]+/[^/]+/[^/]+/n[0-9]+_seed[0-9]+|oracle/.+/n[0-9]+_seed[0-9]+_s[0-9]+)\.parquet|^    output: .*/validation/[^/,]+_calibration\.json' <<<"$plan" \
        | sed -E 's/^    output: //; s/,.*//' | sed -E 's#^(.*/eval/[^/]+/([^/]+)/.*)$#\2 \1#; s#^([^ ]*/oracle/.*)$#oracle \1#; s#^([^ ]*/validation/.*)$#calibration \1#')
targets=()
for s in "${order[@]}" $(cut -d' ' -f1 <<<"$cells" | sort -u | grep -vxF -f <(printf '%s\n' "${order[@]}")); do
  while read -r t; do [ -n "$t" ] && targets+=("$t"); done < <(awk -v s="$s" '$1 == s {print $2}' <<<"$cells" | sort -V)
done
if [ "${LIST:-0}" = 1 ]; then printf '%s\n' "${targets[@]}"; exit 0; fi
[ ${#targets[@]} -gt 0 ] || { echo "protocol_queue: every cell is in results/: run snakemake … all"; exit 0; }
echo "protocol_queue: ${#targets[@]} cells to restore or compute"
CACHE=output_cache exec scripts/validation_cells.sh workflow/configs/shipped.yaml "${1:-4}" "${targets[@]}"
