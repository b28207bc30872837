#!/usr/bin/env bash
# The paired comparisons of reports/table1-real-diffusion-sdf/paired.md: the Diffusion-SDF baseline on
# real targets against Radar2Shape trained on the same recipe (reports/table1-real/, Stage 1 60 epochs,
# circular roll padding, seed 0), the shipped real model and the radar lookup; full and partial
# observability, from the per-shape score files the reports keep (scores/); and the scores per class
# (reports/table1-real-diffusion-sdf/per_class.md, full observability).
#   bash scripts/table1_real_diffusion_sdf_paired.sh      (after `radar2shape sweep table1-real-diffusion-sdf`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-diffusion-sdf
S=$R/scores
T=reports/table1-real/scores
L=reports/table1-real-long/scores
PY=${PY:-.venv/bin/python}
pairs=()
for obs in full partial; do
  pairs+=(--pair "Radar2Shape (same recipe) - Diffusion-SDF, $obs" $T/radar2shape_circ-$obs-seed0.csv $S/diffusion_sdf-$obs.csv)
  pairs+=(--pair "shipped real model - Diffusion-SDF, $obs" $L/radar2shape_circ_steps12k-$obs-seed0.csv $S/diffusion_sdf-$obs.csv)
  pairs+=(--pair "Diffusion-SDF - nearest neighbour, $obs" $S/diffusion_sdf-$obs.csv $L/nearest-$obs.csv)
done
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class.md \
  --run "Radar2Shape (real model, shipped)" $L/radar2shape_circ_steps12k-full-seed0.csv \
  --run "Radar2Shape (same recipe)" $T/radar2shape_circ-full-seed0.csv \
  --run "Diffusion-SDF" $S/diffusion_sdf-full.csv \
  --run "Nearest neighbour" $L/nearest-full.csv \
  --run "Mean shape" $T/mean_shape-full.csv
