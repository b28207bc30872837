#!/usr/bin/env bash
# The paired comparisons of reports/rollsym-medium-reduce/paired.md: the 200-epoch profile U-Net's draws
# combined by their median, or 32 of them, against the mean of 8 of the same checkpoint and against InvRT
# (rollsym-medium's seed-0 rows); the 500-epoch U-Net's median of 32 (rollsym-medium-longer-median) against
# its mean of 8 and against InvRT; and the retrained checkpoints' mean of 8 against the committed 200- and
# 500-epoch rows (how closely a retrain reproduces them).
#   bash scripts/rollsym_medium_reduce_paired.sh    (after `radar2shape sweep rollsym-medium-reduce` and
#                                                     `radar2shape sweep rollsym-medium-longer-median`)
set -euo pipefail
cd "$(dirname "$0")/.."
S=reports/rollsym-medium-reduce/scores
C=reports/rollsym-medium/scores
L=reports/rollsym-medium-longer-median/scores
PY=${PY:-.venv/bin/python}
source scripts/rollsym_scores.sh
pairs=()
for setting in full-medium full-high partial-medium partial-high; do
  obs=${setting%-*} noise=${setting#*-}
  pairs+=(--pair "mean of 8, retrained - committed, $obs, $noise noise" $S/unet_long-$setting.csv "$(unet_200 $setting)")
  pairs+=(--pair "mean of 8 - InvRT, $obs, $noise noise" $S/unet_long-$setting.csv $C/invrt-$setting-seed0.csv)
  for variant in median8 mean32 median32; do
    pairs+=(--pair "$variant - mean of 8, $obs, $noise noise" $S/unet_$variant-$setting.csv $S/unet_long-$setting.csv)
    pairs+=(--pair "$variant - InvRT, $obs, $noise noise" $S/unet_$variant-$setting.csv $C/invrt-$setting-seed0.csv)
  done
done
for setting in full-low full-medium full-high partial-low; do
  obs=${setting%-*} noise=${setting#*-}
  pairs+=(--pair "500 epochs, mean of 8, retrained - committed, $obs, $noise noise" $L/unet_500-$setting.csv \
          reports/rollsym-medium-longer/scores/unet_500-$setting.csv)
  pairs+=(--pair "500 epochs, median32 - mean of 8, $obs, $noise noise" $L/unet_500_median32-$setting.csv $L/unet_500-$setting.csv)
  pairs+=(--pair "500 epochs, median32 - InvRT, $obs, $noise noise" $L/unet_500_median32-$setting.csv $C/invrt-$setting-seed0.csv)
done
"$PY" scripts/paired_scores.py --out reports/rollsym-medium-reduce/paired.md --metrics iou_s match_s iou_r "${pairs[@]}"
