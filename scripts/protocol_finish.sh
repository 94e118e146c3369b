#!/usr/bin/env bash
# The protocol rerun's last step, once scripts/protocol_queue.sh has every cell in results/: build every
# table, figure and page of `all` from those cells, publish them (tables and figures into paper_figures/,
# cells computed here into output_cache/), the same for Table II's final readings on seed 0
# (paper_figures/table_ii_final/), prune the output_cache/ entries no result links to any more
# (cells of superseded hashes: they stay in git's history) and rewrite README's generated blocks.
# Nothing is pruned or published unless `all` finished. COMMIT=1 commits the outcome.
#
#   scripts/protocol_finish.sh                 # JOBS=2 by default
#   COMMIT=1 scripts/protocol_finish.sh
set -euo pipefail
cd "$(dirname "$0")/.."
py=${PYTHON:-.venv/bin/python}
configs=(config.yaml workflow/configs/shipped.yaml)
left=$(LIST=1 scripts/protocol_queue.sh | grep -c . || true)
if [ "$left" != 0 ]; then
  echo "protocol_finish: $left cells are not in results/ yet: run scripts/protocol_queue.sh first" >&2
  exit 2
fi
"$py" -m snakemake -j"${JOBS:-2}" --configfile "${configs[@]}" --profile profiles/shipped all
"$py" -m madpinn publish --config "${configs[@]}"
# Table II's final readings on seed 0 (issue 60; their cells are kept in output_cache/ too): their page,
# so that their cells are linked from results/ before the pruning below
final=(workflow/configs/table_ii_final.yaml)
"$py" -m snakemake -j"${JOBS:-2}" --configfile "${configs[@]}" "${final[@]}" --profile profiles/shipped table_ii_readings
"$py" -m madpinn publish --config "${configs[@]}" "${final[@]}" --figures-to paper_figures/table_ii_final
# every live entry is the target of a link in results/ (output_cache/README.md); the rest is superseded
live=$(mktemp)
find results -type l -exec readlink -f {} \; | xargs -r -n1 basename | sort -u > "$live"
stale=$(cd output_cache && ls | grep -vx README.md | sort | comm -23 - "$live")
rm -f "$live"
n=$(grep -c . <<<"$stale" || true)
echo "protocol_finish: pruning $n superseded output_cache/ files"
[ "$n" = 0 ] || (cd output_cache && xargs rm -f <<<"$stale")
"$py" scripts/update_readme.py
if [ "${COMMIT:-0}" = 1 ]; then
  git add -A paper_figures README.md && git add -A -f output_cache
  git commit -q -m "protocol rerun finished: tables, figures and pages of all published; $n superseded output_cache/ files pruned" \
    -- paper_figures README.md output_cache
fi
