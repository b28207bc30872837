#!/usr/bin/env bash
# The paired comparisons of reports/table1-real-long/paired.md: the long real-target Stage 2 against
# table1-real's circular seed-0 rows (same data, Stage-1 command, seed and protocol; 1,560 steps) and
# against the nearest-neighbour lookup, from the per-shape score files both reports keep (scores/).
#   bash scripts/table1_real_long_paired.sh      (after `radar2shape sweep table1-real-long`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-long
S=$R/scores
C=reports/table1-real/scores
PY=${PY:-.venv/bin/python}
pairs=()
for obs in full partial; do
  pairs+=(--pair "11,960 steps - 1,560 steps (table1-real circular), $obs" $S/radar2shape_circ_steps12k-$obs-seed0.csv $C/radar2shape_circ-$obs-seed0.csv)
  pairs+=(--pair "11,960 steps - nearest neighbour, $obs" $S/radar2shape_circ_steps12k-$obs-seed0.csv $S/nearest-$obs.csv)
done
pairs+=(--pair "mean of 8 samples - one sample, full" $S/radar2shape_circ_steps12k_k8-full-seed0.csv $S/radar2shape_circ_steps12k-full-seed0.csv)
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
