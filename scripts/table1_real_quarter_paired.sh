#!/usr/bin/env bash
# The paired comparisons of reports/table1-real-quarter/: Radar2Shape with every shape learned in the
# quarter turn nearest its heading (Stage 1 on the 8 axis-aligned poses, canonical_turn_step Stage 2)
# against the shipped real model (table1-real-long), the canonical-heading model (table1-real-heading)
# and the nearest-neighbour lookup; its Stage 1 scored on test and training objects beside the shipped
# and the canonical-only Stage 1; all from per-shape score files.
#   bash scripts/table1_real_quarter_paired.sh      (after `radar2shape sweep table1-real-quarter`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-quarter
S=$R/scores
L=reports/table1-real-long/scores
H=reports/table1-real-heading/scores
N=reports/table1-real-stage1-noaug/ceiling_scores.csv
PY=${PY:-.venv/bin/python}
"$PY" scripts/stage1_fit_gap.py --run runs/table1-real-quarter/radar2shape_quarter_stage1 --train-shapes 60 \
  --out $R/fit_gap.md --scores $R/ceiling_scores.csv
"$PY" scripts/paired_scores.py --metrics ceiling_iou ceiling_fscore_1pct ceiling_chamfer_l2_x1e3 --out $R/paired_ceiling.md \
  --pair "quarter turns - shipped Stage 1" $R/ceiling_scores.csv $L/radar2shape_circ_steps12k-full-seed0.csv \
  --pair "quarter turns - canonical heading only" $R/ceiling_scores.csv $N
pairs=()
for obs in full partial; do
  pairs+=(--pair "quarter turns - shipped real model, $obs" $S/radar2shape_quarter-$obs-seed0.csv $L/radar2shape_circ_steps12k-$obs-seed0.csv)
  pairs+=(--pair "quarter turns - canonical heading, $obs" $S/radar2shape_quarter-$obs-seed0.csv $H/radar2shape_heading-$obs-seed0.csv)
  pairs+=(--pair "quarter turns - nearest neighbour, $obs" $S/radar2shape_quarter-$obs-seed0.csv $L/nearest-$obs.csv)
done
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class.md \
  --run "Radar2Shape, quarter turns" $S/radar2shape_quarter-full-seed0.csv \
  --run "Radar2Shape, canonical heading" $H/radar2shape_heading-full-seed0.csv \
  --run "Radar2Shape (shipped real model)" $L/radar2shape_circ_steps12k-full-seed0.csv \
  --run "Nearest neighbour" $L/nearest-full.csv \
  --run "Stage 1, quarter turns" $R/ceiling_scores.csv \
  --run "Stage 1, canonical heading only" $N
