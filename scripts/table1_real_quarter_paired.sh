#!/usr/bin/env bash
# reports/table1-real-quarter/: the Stage 1 trained on the 8 axis-aligned poses of every training object
# (quarter turns, each plain and mirrored) scored on test and training objects, paired per object with
# the shipped Stage 1 (every roll step) and the canonical-only Stage 1, and per class.
#   bash scripts/table1_real_quarter_paired.sh      (after `radar2shape sweep table1-real-quarter`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-quarter
SHIPPED=reports/table1-real-long/scores/radar2shape_circ_steps12k-full-seed0.csv
CANONICAL=reports/table1-real-stage1-noaug/ceiling_scores.csv
PY=${PY:-.venv/bin/python}
"$PY" scripts/stage1_fit_gap.py --run runs/table1-real-quarter/radar2shape_quarter_stage1 --train-shapes 60 \
  --out $R/fit_gap.md --scores $R/ceiling_scores.csv
"$PY" scripts/paired_scores.py --metrics ceiling_iou ceiling_fscore_1pct ceiling_chamfer_l2_x1e3 --out $R/paired_ceiling.md \
  --pair "quarter turns - shipped Stage 1 (every roll step)" $R/ceiling_scores.csv $SHIPPED \
  --pair "quarter turns - canonical heading only" $R/ceiling_scores.csv $CANONICAL
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class_ceiling.md \
  --run "shipped Stage 1 (every roll step)" $SHIPPED \
  --run "canonical heading only" $CANONICAL \
  --run "quarter turns" $R/ceiling_scores.csv
