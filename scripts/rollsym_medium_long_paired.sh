#!/usr/bin/env bash
# The paired comparisons of reports/rollsym-medium-long/paired.md: the profile U-Net trained 200
# epochs against rollsym-medium's seed-0 U-Net (60 epochs) and InvRT rows in the same setting, from
# the per-shape score files the reports keep (scores/); low and high noise from rollsym-medium-long,
# medium from rollsym-medium-long-mid; the U-Net trained 500 epochs (rollsym-medium-longer, four
# settings) against the 200-epoch U-Net and InvRT; and its seed-1 runs (rollsym-medium-longer-seed1)
# against InvRT's seed 1.
#   bash scripts/rollsym_medium_long_paired.sh      (after `radar2shape sweep` of rollsym-medium-long,
#                                                     rollsym-medium-long-mid, rollsym-medium-longer
#                                                     and rollsym-medium-longer-seed1)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/rollsym-medium-long
S=$R/scores
C=reports/rollsym-medium/scores
X=reports/rollsym-medium-longer/scores
X1=reports/rollsym-medium-longer-seed1/scores
PY=${PY:-.venv/bin/python}
source scripts/rollsym_scores.sh
pairs=()
for obs in full partial; do
  for noise in low medium high; do
    long=$(unet_200 $obs-$noise)
    pairs+=(--pair "U-Net 200 epochs - U-Net 60 epochs, $obs, $noise noise" $long $C/unet-$obs-$noise-seed0.csv)
    pairs+=(--pair "U-Net 200 epochs - InvRT, $obs, $noise noise" $long $C/invrt-$obs-$noise-seed0.csv)
  done
done
for setting in full-low full-medium full-high partial-low; do
  obs=${setting%-*} noise=${setting#*-}
  long=$(unet_200 $setting)
  pairs+=(--pair "U-Net 500 epochs - U-Net 200 epochs, $obs, $noise noise" $X/unet_500-$setting.csv $long)
  pairs+=(--pair "U-Net 500 epochs - InvRT, $obs, $noise noise" $X/unet_500-$setting.csv $C/invrt-$setting-seed0.csv)
done
for setting in full-medium full-high; do
  obs=${setting%-*} noise=${setting#*-}
  pairs+=(--pair "U-Net 500 epochs - InvRT, seed 1, $obs, $noise noise" $X1/unet_500-$setting.csv $C/invrt-$setting-seed1.csv)
done
"$PY" scripts/paired_scores.py --out $R/paired.md --metrics iou_s match_s iou_r "${pairs[@]}"
