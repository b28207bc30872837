#!/usr/bin/env bash
# Paired comparisons of a real-target grid's Radar2Shape rows against the shipped real model
# (table1-real-long's seed 0: same data and test protocol) and against the nearest-neighbour
# lookup, from the per-shape scores of both reports; writes reports/GRID/paired.md.
#   bash scripts/table1_real_paired.sh table1-real-seeds    (after `radar2shape sweep table1-real-seeds`)
#   bash scripts/table1_real_paired.sh table1-real-wide
set -euo pipefail
cd "$(dirname "$0")/.."
GRID=${1:?usage: scripts/table1_real_paired.sh GRID (a real-target grid whose report is in reports/GRID)}
R=reports/$GRID
S=$R/scores
L=reports/table1-real-long/scores
PY=${PY:-.venv/bin/python}
[ -d "$S" ] || { echo "error: $S does not exist: run 'radar2shape sweep $GRID' first" >&2; exit 2; }
pairs=()
for obs in full partial; do
  for a in $S/radar2shape*-$obs*.csv; do
    [ -e "$a" ] || continue
    run=$(basename "$a" .csv)
    pairs+=(--pair "$run - shipped model (seed 0), $obs" $a $L/radar2shape_circ_steps12k-$obs-seed0.csv)
    pairs+=(--pair "$run - nearest neighbour, $obs" $a $L/nearest-$obs.csv)
  done
done
[ ${#pairs[@]} -gt 0 ] || { echo "error: no Radar2Shape scores in $S" >&2; exit 2; }
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
