#!/usr/bin/env bash
# The paired comparisons of reports/table1-real-seeds/paired.md: Stage 2 of seeds 1 and 2 against the
# shipped real model (table1-real-long's seed 0: the same Stage 1, data, recipe and test protocol)
# and against the nearest-neighbour lookup, from both reports' per-shape scores.
#   bash scripts/table1_real_seeds_paired.sh      (after `radar2shape sweep table1-real-seeds`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-seeds
S=$R/scores
L=reports/table1-real-long/scores
PY=${PY:-.venv/bin/python}
pairs=()
for obs in full partial; do
  pairs+=(--pair "seed 1 - seed 0 (shipped), $obs" $S/radar2shape_circ_steps12k-$obs-seed1.csv $L/radar2shape_circ_steps12k-$obs-seed0.csv)
  pairs+=(--pair "seed 1 - nearest neighbour, $obs" $S/radar2shape_circ_steps12k-$obs-seed1.csv $L/nearest-$obs.csv)
  if [ -f $S/radar2shape_circ_steps12k-$obs-seed2.csv ]; then
    pairs+=(--pair "seed 2 - seed 0 (shipped), $obs" $S/radar2shape_circ_steps12k-$obs-seed2.csv $L/radar2shape_circ_steps12k-$obs-seed0.csv)
    pairs+=(--pair "seed 2 - nearest neighbour, $obs" $S/radar2shape_circ_steps12k-$obs-seed2.csv $L/nearest-$obs.csv)
  fi
done
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
