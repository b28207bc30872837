#!/usr/bin/env bash
# The paired comparisons of reports/table1-medium/paired.md, from the per-shape score files the
# report keeps (scores/) and the two archives of earlier grid states (stage2-40-epochs/: Stage 2
# for 40 epochs scored with its last weights; stage1-40-epochs/: the same on the 40-epoch Stage 1).
#   bash scripts/table1_medium_paired.sh          (after `make report GRID=table1-medium`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-medium
S=$R/scores
E40=$R/stage2-40-epochs/scores
S40=$R/stage1-40-epochs/scores
PY=${PY:-.venv/bin/python}
"$PY" scripts/paired_scores.py --out $R/paired.md \
  --pair "tuned - as in the paper, full" $S/radar2shape-full-seed0.csv $S/radar2shape_paper-full.csv \
  --pair "tuned - as in the paper, partial" $S/radar2shape-partial-seed0.csv $S/radar2shape_paper-partial.csv \
  --pair "Stage 2 80 epochs + EMA - 40 epochs, full" $S/radar2shape-full-seed0.csv $E40/radar2shape-full-seed0.csv \
  --pair "Stage 2 80 epochs + EMA - 40 epochs, partial" $S/radar2shape-partial-seed0.csv $E40/radar2shape-partial-seed0.csv \
  --pair "tuned - as in the paper, 40 epochs, full" $E40/radar2shape-full-seed0.csv $E40/radar2shape_paper-full.csv \
  --pair "tuned - as in the paper, 40 epochs, partial" $E40/radar2shape-partial-seed0.csv $E40/radar2shape_paper-partial.csv \
  --pair "Stage 1 60 - 40 epochs (Stage 2 40 epochs), full" $E40/radar2shape-full-seed0.csv $S40/radar2shape-full-seed0.csv \
  --pair "Stage 1 60 - 40 epochs (Stage 2 40 epochs), partial" $E40/radar2shape-partial-seed0.csv $S40/radar2shape-partial-seed0.csv \
  --pair "tuned - nearest neighbour, full" $S/radar2shape-full-seed0.csv $S/nearest-full.csv \
  --pair "tuned - nearest neighbour, partial" $S/radar2shape-partial-seed0.csv $S/nearest-partial.csv \
  --pair "tuned - TMNet, full" $S/radar2shape-full-seed0.csv $S/tmnet-full.csv \
  --pair "tuned - TMNet, partial" $S/radar2shape-partial-seed0.csv $S/tmnet-partial.csv \
  --pair "Stage 1: lr halved every 1,400 steps - every 700" $S/radar2shape_stage1_slowdecay.csv $S/radar2shape_stage1.csv \
  --pair "Stage 1: wide - grid's" $S/radar2shape_stage1_wide.csv $S/radar2shape_stage1.csv \
  --pair "Stage 1: wide - lr halved every 1,400 steps" $S/radar2shape_stage1_wide.csv $S/radar2shape_stage1_slowdecay.csv \
  --pair "Stage 2 on the slow-decay Stage 1 - on the grid's, full" $S/radar2shape_s1slow-full.csv $S/radar2shape-full-seed0.csv \
  --pair "Stage 2 on the wide Stage 1 - on the grid's, full" $S/radar2shape_s1wide-full.csv $S/radar2shape-full-seed0.csv \
  --pair "Stage 2 on the wide Stage 1 - nearest neighbour, full" $S/radar2shape_s1wide-full.csv $S/nearest-full.csv \
  --pair "Stage 1: Radar2Shape's (three levels) - Diffusion-SDF's (one level)" $S/radar2shape_stage1.csv $S/diffusion_sdf_stage1.csv \
  --pair "tuned - Diffusion-SDF, full" $S/radar2shape-full-seed0.csv $S/diffusion_sdf-full-seed0.csv \
  --pair "tuned - Diffusion-SDF, partial" $S/radar2shape-partial-seed0.csv $S/diffusion_sdf-partial-seed0.csv \
  --pair "tuned at Diffusion-SDF's budget (40 epochs, last weights) - Diffusion-SDF, full" $E40/radar2shape-full-seed0.csv $S/diffusion_sdf-full-seed0.csv \
  --pair "tuned at Diffusion-SDF's budget (40 epochs, last weights) - Diffusion-SDF, partial" $E40/radar2shape-partial-seed0.csv $S/diffusion_sdf-partial-seed0.csv \
  --pair "Diffusion-SDF - TMNet, full" $S/diffusion_sdf-full-seed0.csv $S/tmnet-full.csv \
  --pair "Diffusion-SDF - TMNet, partial" $S/diffusion_sdf-partial-seed0.csv $S/tmnet-partial.csv \
  --pair "TMNet - LIST, full" $S/tmnet-full.csv $S/list-full.csv \
  --pair "TMNet - LIST, partial" $S/tmnet-partial.csv $S/list-partial.csv \
  --pair "Diffusion-SDF - LIST, full" $S/diffusion_sdf-full-seed0.csv $S/list-full.csv \
  --pair "Diffusion-SDF - LIST, partial" $S/diffusion_sdf-partial-seed0.csv $S/list-partial.csv \
  --pair "tuned - LIST, full" $S/radar2shape-full-seed0.csv $S/list-full.csv \
  --pair "tuned - LIST, partial" $S/radar2shape-partial-seed0.csv $S/list-partial.csv
