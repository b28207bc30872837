#!/usr/bin/env bash
# The paired comparisons of reports/table1-real-seeds/paired.md: Stage 2 of each seed the grid has
# run against the shipped real model (table1-real-long's seed 0: the same Stage 1, data, recipe and
# test protocol) and against the nearest-neighbour lookup, from both reports' per-shape scores.
#   bash scripts/table1_real_seeds_paired.sh      (after `radar2shape sweep table1-real-seeds`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-seeds
S=$R/scores
L=reports/table1-real-long/scores
PY=${PY:-.venv/bin/python}
pairs=()
for obs in full partial; do
  for a in $S/radar2shape_circ_steps12k-$obs-seed*.csv; do
    seed=${a##*-seed}; seed=${seed%.csv}
    pairs+=(--pair "seed $seed - seed 0 (shipped), $obs" $a $L/radar2shape_circ_steps12k-$obs-seed0.csv)
    pairs+=(--pair "seed $seed - nearest neighbour, $obs" $a $L/nearest-$obs.csv)
  done
done
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
