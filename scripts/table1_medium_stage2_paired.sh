#!/usr/bin/env bash
# The paired comparisons of reports/table1-medium-stage2/paired.md: the longer Stage-2 fits against
# the committed table1-medium rows of the same seed, and the mean of 8 samples against one sample of
# the same checkpoint, from the per-shape score files both reports keep (scores/).
#   bash scripts/table1_medium_stage2_paired.sh      (after `radar2shape sweep table1-medium-stage2`)
set -euo pipefail
cd "$(dirname "$0")/.."
R=reports/table1-medium-stage2
S=$R/scores
C=reports/table1-medium/scores
PY=${PY:-.venv/bin/python}
pairs=()
for obs in full partial; do
  for seed in 0 1 2; do
    pairs+=(--pair "200 epochs - committed, $obs seed $seed" $S/radar2shape_long-$obs-seed$seed.csv $C/radar2shape-$obs-seed$seed.csv)
  done
done
for run in full-seed0 full-seed1 full-seed2 partial-seed0; do
  pairs+=(--pair "200 epochs: mean of 8 - one sample, ${run/-seed/ seed }" $S/radar2shape_long_k8-$run.csv $S/radar2shape_long-$run.csv)
done
pairs+=(--pair "committed: mean of 8 - one sample, full seed 0" $S/radar2shape_k8-full-seed0.csv $C/radar2shape-full-seed0.csv)
pairs+=(--pair "full model fine-tuned on masked radar - 200 epochs on masked radar, partial seed 0" $S/radar2shape_ft-partial-seed0.csv $S/radar2shape_long-partial-seed0.csv)
pairs+=(--pair "full model fine-tuned on masked radar - committed, partial seed 0" $S/radar2shape_ft-partial-seed0.csv $C/radar2shape-partial-seed0.csv)
"$PY" scripts/paired_scores.py --out $R/paired.md "${pairs[@]}"
