#!/usr/bin/env bash
# The paired comparisons of reports/table1-real-faster/paired.md: the real-target Stage 2 retrained at the
# 3x step settings against the shipped real model (the same Stage 1 and test protocol) and the radar
# lookup; the one whose radar encoder started from the parts model's against the shipped model, the
# scratch 3x row and its control (the encoder drawn fresh); full and partial observability, from the
# per-shape score files the reports keep (scores/).
#   bash scripts/table1_real_faster_paired.sh      (after `radar2shape sweep table1-real-faster`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-faster
S=$R/scores
L=reports/table1-real-long/scores
PY=${PY:-.venv/bin/python}
pairs=()
for obs in full partial; do
  pairs+=(--pair "3x settings, 1,000 epochs - shipped, $obs" $S/radar2shape_faster-$obs-seed0.csv $L/radar2shape_circ_steps12k-$obs-seed0.csv)
  pairs+=(--pair "3x settings, 1,000 epochs - nearest neighbour, $obs" $S/radar2shape_faster-$obs-seed0.csv $L/nearest-$obs.csv)
  pairs+=(--pair "encoder from the parts model, 600 epochs - shipped, $obs" $S/radar2shape_partsenc-$obs-seed0.csv $L/radar2shape_circ_steps12k-$obs-seed0.csv)
  pairs+=(--pair "encoder from the parts model, 600 epochs - 3x settings, 1,000 epochs, $obs" $S/radar2shape_partsenc-$obs-seed0.csv $S/radar2shape_faster-$obs-seed0.csv)
  pairs+=(--pair "encoder from the parts model - encoder drawn fresh, 600 epochs each, $obs" $S/radar2shape_partsenc-$obs-seed0.csv $S/radar2shape_enc4-$obs-seed0.csv)
  pairs+=(--pair "encoder from the parts model, 600 epochs - nearest neighbour, $obs" $S/radar2shape_partsenc-$obs-seed0.csv $L/nearest-$obs.csv)
done
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
