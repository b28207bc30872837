#!/usr/bin/env bash
# The paired comparisons of reports/rollsym-medium-reduce/paired.md: the 200-epoch profile U-Net's draws
# combined by their median, or 32 of them, against the mean of 8 of the same checkpoint and against InvRT
# (rollsym-medium's seed-0 rows); and the retrained checkpoints' mean of 8 against the committed
# 200-epoch rows (how closely a retrain reproduces them).
#   bash scripts/rollsym_medium_reduce_paired.sh    (after `radar2shape sweep rollsym-medium-reduce`)
set -euo pipefail
cd "$(dirname "$0")/.."
S=reports/rollsym-medium-reduce/scores
C=reports/rollsym-medium/scores
PY=${PY:-.venv/bin/python}
committed_200() {  # the committed 200-epoch U-Net's scores in setting $1 (<obs>-<noise>)
  case $1 in *-medium) echo "reports/rollsym-medium-long-mid/scores/unet_long-$1.csv" ;;
                    *) echo "reports/rollsym-medium-long/scores/unet_long-$1.csv" ;; esac
}
pairs=()
for setting in full-medium full-high partial-medium partial-high; do
  obs=${setting%-*} noise=${setting#*-}
  pairs+=(--pair "mean of 8, retrained - committed, $obs, $noise noise" $S/unet_long-$setting.csv "$(committed_200 $setting)")
  pairs+=(--pair "mean of 8 - InvRT, $obs, $noise noise" $S/unet_long-$setting.csv $C/invrt-$setting-seed0.csv)
  for variant in median8 mean32 median32; do
    pairs+=(--pair "$variant - mean of 8, $obs, $noise noise" $S/unet_$variant-$setting.csv $S/unet_long-$setting.csv)
    pairs+=(--pair "$variant - InvRT, $obs, $noise noise" $S/unet_$variant-$setting.csv $C/invrt-$setting-seed0.csv)
  done
done
"$PY" scripts/paired_scores.py --out reports/rollsym-medium-reduce/paired.md --metrics iou_s match_s iou_r "${pairs[@]}"
