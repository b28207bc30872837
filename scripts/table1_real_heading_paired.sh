#!/usr/bin/env bash
# The paired comparisons of reports/table1-real-heading/paired.md: Radar2Shape with every shape learned
# in its canonical heading (canonical Stage 1, canonical_heading Stage 2, heading found by a PO search)
# against the shipped real model's rows (table1-real-long: roll-augmented Stage 1 and Stage 2, same Stage-2
# recipe, seed and test protocol) and against the nearest-neighbour lookup, from the per-shape score files.
#   bash scripts/table1_real_heading_paired.sh      (after `radar2shape sweep table1-real-heading`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-real-heading
S=$R/scores
L=reports/table1-real-long/scores
PY=${PY:-.venv/bin/python}
pairs=()
for obs in full partial; do
  pairs+=(--pair "canonical heading - shipped real model, $obs" $S/radar2shape_heading-$obs-seed0.csv $L/radar2shape_circ_steps12k-$obs-seed0.csv)
  pairs+=(--pair "canonical heading - nearest neighbour, $obs" $S/radar2shape_heading-$obs-seed0.csv $L/nearest-$obs.csv)
done
pairs+=(--pair "heading by PO search - true heading given (oracle), full" $S/radar2shape_heading-full-seed0.csv $S/radar2shape_heading_oracle-full-seed0.csv)
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
"$PY" scripts/per_class_scores.py --data data/real --out $R/per_class.md \
  --run "Radar2Shape, canonical heading" $S/radar2shape_heading-full-seed0.csv \
  --run "the same, true heading given" $S/radar2shape_heading_oracle-full-seed0.csv \
  --run "Radar2Shape (shipped real model)" $L/radar2shape_circ_steps12k-full-seed0.csv \
  --run "Nearest neighbour" $L/nearest-full.csv
