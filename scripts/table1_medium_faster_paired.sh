#!/usr/bin/env bash
# The paired comparisons of reports/table1-medium-faster/paired.md: the rows trained at 3x the shapes a
# second against the committed table1-medium rows and the table1-medium-fast rows of the same seed, the
# third-of-the-time schedules against the committed rows, and LIST with bfloat16 against its committed row,
# from the per-shape score files the reports keep (scores/).
#   bash scripts/table1_medium_faster_paired.sh      (after `radar2shape sweep table1-medium-faster`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-medium-faster
S=$R/scores
C=reports/table1-medium/scores
F=reports/table1-medium-fast/scores
PY=${PY:-.venv/bin/python}
pairs=()
for seed in 0 1 2; do
  pairs+=(--pair "faster - committed, full seed $seed" $S/radar2shape-full-seed$seed.csv $C/radar2shape-full-seed$seed.csv)
  pairs+=(--pair "faster - fast, full seed $seed" $S/radar2shape-full-seed$seed.csv $F/radar2shape-full-seed$seed.csv)
done
pairs+=(--pair "faster - committed, Stage 1 (ceiling)" $S/radar2shape_stage1.csv $C/radar2shape_stage1.csv)
pairs+=(--pair "faster - fast, Stage 1 (ceiling)" $S/radar2shape_stage1.csv $F/radar2shape_stage1.csv)
for seed in 0 1 2; do
  pairs+=(--pair "third of the time - committed, full seed $seed" $S/radar2shape_third-full-seed$seed.csv $C/radar2shape-full-seed$seed.csv)
done
pairs+=(--pair "third of the time - committed, partial seed 0" $S/radar2shape_third-partial-seed0.csv $C/radar2shape-partial-seed0.csv)
pairs+=(--pair "third of the time - committed, Stage 1 (ceiling)" $S/radar2shape_stage1third.csv $C/radar2shape_stage1.csv)
pairs+=(--pair "LIST with bfloat16 - committed, full" $S/list-full.csv $C/list-full.csv)
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
