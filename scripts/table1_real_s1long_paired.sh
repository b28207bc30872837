#!/usr/bin/env bash
# The paired comparisons of reports/table1-real-s1long/paired.md: Stage 2 on the 200-epoch Stage 1
# against table1-real-long's rows (the same data, seed, Stage-2 command and test protocol on the
# 60-epoch Stage 1) and against the nearest-neighbour lookup, from both reports' per-shape scores.
#   bash scripts/table1_real_s1long_paired.sh      (after `radar2shape sweep table1-real-s1long`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-s1long
S=$R/scores
L=reports/table1-real-long/scores
PY=${PY:-.venv/bin/python}
pairs=()
for obs in full partial; do
  pairs+=(--pair "Stage 1 200 epochs - 60 epochs, Stage 2 11,960 steps each, $obs" $S/radar2shape_s1long_steps12k-$obs-seed0.csv $L/radar2shape_circ_steps12k-$obs-seed0.csv)
  pairs+=(--pair "Stage 2 4,160 steps - 11,960 steps, Stage 1 200 epochs, $obs" $S/radar2shape_s1long-$obs-seed0.csv $S/radar2shape_s1long_steps12k-$obs-seed0.csv)
  pairs+=(--pair "Stage 1 200 epochs + Stage 2 11,960 steps - nearest neighbour, $obs" $S/radar2shape_s1long_steps12k-$obs-seed0.csv $L/nearest-$obs.csv)
done
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
