#!/usr/bin/env bash
# Scores of reports/table1-real-stage1-parts-init/: the real-target Stage 1 started from the shipped parts
# model's Stage 1, and the shipped real model's Stage 1 scored on the same data (the same script, the same
# test and training objects), paired per object, per class, and its learning curve.
#   bash scripts/table1_real_stage1_parts_init.sh    (after `radar2shape sweep table1-real-stage1-parts-init`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-stage1-parts-init
RUN=runs/table1-real-stage1-parts-init/radar2shape_stage1_partsinit
PY=${PY:-.venv/bin/python}
mkdir -p $R
"$PY" scripts/stage1_fit_gap.py --run $RUN --train-shapes 60 --out $R/fit_gap.md --scores $R/ceiling_scores.csv
"$PY" scripts/stage1_fit_gap.py --run $RUN --ckpt src/radar2shape/weights/radar2shape_real.ckpt --train-shapes 60 \
    --out $R/fit_gap_shipped.md --scores $R/ceiling_scores_shipped.csv
"$PY" scripts/learning_curves.py --grid table1-real-stage1-parts-init --out $R
"$PY" scripts/paired_scores.py --metrics ceiling_iou ceiling_fscore_1pct ceiling_chamfer_l2_x1e3 --out $R/paired_ceiling.md \
    --pair "started from the parts Stage 1 - shipped real Stage 1" $R/ceiling_scores.csv $R/ceiling_scores_shipped.csv
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class_ceiling.md \
    --run "shipped real Stage 1" $R/ceiling_scores_shipped.csv \
    --run "started from the parts Stage 1" $R/ceiling_scores.csv
# Stage 2 on it against the shipped real model and the lookup (table1-real-long's rows on the same objects).
L=reports/table1-real-long/scores
"$PY" scripts/paired_scores.py --out $R/paired.md \
    --pair "parts-started Stage 1 - shipped real model, full" $R/scores/radar2shape_partsinit-full-seed0.csv $L/radar2shape_circ_steps12k-full-seed0.csv \
    --pair "parts-started Stage 1 - shipped real model, partial" $R/scores/radar2shape_partsinit-partial-seed0.csv $L/radar2shape_circ_steps12k-partial-seed0.csv \
    --pair "parts-started Stage 1 - nearest neighbour, full" $R/scores/radar2shape_partsinit-full-seed0.csv $L/nearest-full.csv \
    --pair "parts-started Stage 1 - nearest neighbour, partial" $R/scores/radar2shape_partsinit-partial-seed0.csv $L/nearest-partial.csv
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class.md \
    --run "shipped real model" $L/radar2shape_circ_steps12k-full-seed0.csv \
    --run "parts-started Stage 1" $R/scores/radar2shape_partsinit-full-seed0.csv \
    --run "nearest neighbour" $L/nearest-full.csv
