#!/usr/bin/env bash
# reports/table1-real-front/: Radar2Shape with aircraft and ships learned in their stored heading, its Stage 2
# trained on the seed-1 Stage 1 (radar2shape_front_s1seed1_*) and on the shipped model's Stage 1
# (radar2shape_front_shippeds1_*), paired per object with the shipped real model, the same recipe on the seed-0
# Stage 1 and the nearest-neighbour lookup, and per class.
#   bash scripts/table1_real_front_s1seed1_paired.sh   (after `radar2shape sweep table1-real-front`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-front
S=$R/scores
L=reports/table1-real-long/scores
PY=${PY:-.venv/bin/python}
# the Stage 1 under this Stage 2 (its run folder as the sweep left it; a rebuilt dataset or another machine
# may train it to another ceiling than the committed ceiling_scores_seed1.csv, which is paired here)
"$PY" scripts/stage1_fit_gap.py --run runs/table1-real-front/radar2shape_front_stage1_seed1 --train-shapes 60 \
  --out $R/fit_gap_s1seed1.md --scores $R/ceiling_scores_s1seed1.csv
"$PY" scripts/paired_scores.py --metrics ceiling_iou ceiling_fscore_1pct ceiling_chamfer_l2_x1e3 --out $R/paired_ceiling_s1seed1.md \
  --pair "seed 1, this run - seed 1, committed run" $R/ceiling_scores_s1seed1.csv $R/ceiling_scores_seed1.csv
pairs=()
for obs in full partial; do
  pairs+=(--pair "front classes, Stage 1 seed 1 - shipped real model, $obs" $S/radar2shape_front_s1seed1-$obs-seed0.csv $L/radar2shape_circ_steps12k-$obs-seed0.csv)
  pairs+=(--pair "front classes, Stage 1 seed 1 - Stage 1 seed 0, $obs" $S/radar2shape_front_s1seed1-$obs-seed0.csv $S/radar2shape_front-$obs-seed0.csv)
  pairs+=(--pair "front classes, Stage 1 seed 1 - nearest neighbour, $obs" $S/radar2shape_front_s1seed1-$obs-seed0.csv $L/nearest-$obs.csv)
done
"$PY" scripts/paired_scores.py --out $R/paired_s1seed1.md "${pairs[@]}"
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class_s1seed1.md \
  --run "front classes canonical, Stage 1 seed 1" $S/radar2shape_front_s1seed1-full-seed0.csv \
  --run "front classes canonical, Stage 1 seed 0" $S/radar2shape_front-full-seed0.csv \
  --run "Radar2Shape (shipped real model)" $L/radar2shape_circ_steps12k-full-seed0.csv \
  --run "Nearest neighbour" $L/nearest-full.csv \
  --run "Stage 1 seed 1 (ceiling)" $R/ceiling_scores_s1seed1.csv
# on the shipped model's Stage 1: does Stage 1 or Stage 2 lose the classes without a front?
"$PY" scripts/paired_scores.py --out $R/paired_shippeds1.md \
  --pair "front classes, shipped Stage 1 - shipped real model, full" $S/radar2shape_front_shippeds1-full-seed0.csv $L/radar2shape_circ_steps12k-full-seed0.csv \
  --pair "front classes, shipped Stage 1 - front Stage 1 seed 0, full" $S/radar2shape_front_shippeds1-full-seed0.csv $S/radar2shape_front-full-seed0.csv \
  --pair "front classes, shipped Stage 1 - shipped real model, partial" $S/radar2shape_front_shippeds1-partial-seed0.csv $L/radar2shape_circ_steps12k-partial-seed0.csv
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class_shippeds1.md \
  --run "front classes canonical, shipped Stage 1" $S/radar2shape_front_shippeds1-full-seed0.csv \
  --run "front classes canonical, front Stage 1 seed 0" $S/radar2shape_front-full-seed0.csv \
  --run "front classes canonical, front Stage 1 seed 1" $S/radar2shape_front_s1seed1-full-seed0.csv \
  --run "Radar2Shape (shipped real model)" $L/radar2shape_circ_steps12k-full-seed0.csv
