#!/usr/bin/env bash
# reports/table1-real-front/: Radar2Shape with aircraft and ships learned in their stored heading and the
# other classes turned, paired per object with the shipped real model (table1-real-long), the model with
# every class canonical (table1-real-heading) and the nearest-neighbour lookup; its Stage 1 scored on
# test and training objects beside the shipped and the canonical-only Stage 1; and per class.
#   bash scripts/table1_real_front_paired.sh      (after `radar2shape sweep table1-real-front`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-front
S=$R/scores
L=reports/table1-real-long/scores
H=reports/table1-real-heading/scores
CANONICAL=reports/table1-real-stage1-noaug/ceiling_scores.csv
PY=${PY:-.venv/bin/python}
for seed in "" _seed1; do  # the Stage 1 the rows use, and its seed-1 rerun
  "$PY" scripts/stage1_fit_gap.py --run runs/table1-real-front/radar2shape_front_stage1$seed --train-shapes 60 \
    --out $R/fit_gap$seed.md --scores $R/ceiling_scores$seed.csv
done
pairs=(--pair "front classes canonical - shipped real model, Stage 1" $R/ceiling_scores.csv $L/radar2shape_circ_steps12k-full-seed0.csv
       --pair "front classes canonical - every class canonical, Stage 1" $R/ceiling_scores.csv $CANONICAL)
"$PY" scripts/paired_scores.py --metrics ceiling_iou ceiling_fscore_1pct ceiling_chamfer_l2_x1e3 --out $R/paired_ceiling.md "${pairs[@]}"
pairs=()
for obs in full partial; do
  pairs+=(--pair "front classes canonical - shipped real model, $obs" $S/radar2shape_front-$obs-seed0.csv $L/radar2shape_circ_steps12k-$obs-seed0.csv)
  pairs+=(--pair "front classes canonical - every class canonical, $obs" $S/radar2shape_front-$obs-seed0.csv $H/radar2shape_heading-$obs-seed0.csv)
  pairs+=(--pair "front classes canonical - nearest neighbour, $obs" $S/radar2shape_front-$obs-seed0.csv $L/nearest-$obs.csv)
done
pairs+=(--pair "heading by PO search - true heading given (oracle), full" $S/radar2shape_front-full-seed0.csv $S/radar2shape_front_oracle-full-seed0.csv)
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class.md \
  --run "Radar2Shape, front classes canonical" $S/radar2shape_front-full-seed0.csv \
  --run "the same, true heading given" $S/radar2shape_front_oracle-full-seed0.csv \
  --run "Radar2Shape, every class canonical" $H/radar2shape_heading-full-seed0.csv \
  --run "Radar2Shape (shipped real model)" $L/radar2shape_circ_steps12k-full-seed0.csv \
  --run "Nearest neighbour" $L/nearest-full.csv \
  --run "Stage 1, every class canonical" $CANONICAL
# the seed-1 rerun of its Stage 1 (radar2shape_front_stage1_seed1), paired and per class
"$PY" scripts/paired_scores.py --metrics ceiling_iou ceiling_fscore_1pct ceiling_chamfer_l2_x1e3 --out $R/paired_ceiling_seed1.md \
  --pair "front classes canonical seed 1 - shipped Stage 1" $R/ceiling_scores_seed1.csv $L/radar2shape_circ_steps12k-full-seed0.csv \
  --pair "front classes canonical seed 1 - canonical heading only" $R/ceiling_scores_seed1.csv $CANONICAL \
  --pair "front classes canonical seed 1 - seed 0" $R/ceiling_scores_seed1.csv $R/ceiling_scores.csv
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class_ceiling.md \
  --run "shipped Stage 1" $L/radar2shape_circ_steps12k-full-seed0.csv \
  --run "canonical heading only" $CANONICAL \
  --run "front classes canonical, seed 0" $R/ceiling_scores.csv \
  --run "front classes canonical, seed 1" $R/ceiling_scores_seed1.csv
