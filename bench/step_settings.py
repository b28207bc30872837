"""Benchmark: what settings beyond table1-medium-fast would buy in shapes/s, before any quality run.

    python bench/step_settings.py [--rounds 3] [--threads 2]

The same synthetic step as bench/train_throughput.py (model losses, backward, the model's optimizer),
for Stage 1 and Stage 2 at the table1-medium settings (reference kernels, float32: the committed rows),
the table1-medium-fast settings, and candidate settings that change what a step computes: fewer
encoder points or SDF samples (Stage 1), a larger batch, bfloat16, a narrower radar ResNet (Stage 2).
The settings take turns for ``--rounds`` rounds and each keeps its best; the ratio is against the
table1-medium row of the same stage, in the same run. Speed only: each candidate changes what the
model learns, so none is adopted without its own fit (docs/throughput.md, "What limits"); the two
marked table1-medium-faster there were fitted by that grid ("The table1-medium Radar2Shape rows, at 3x").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import train_throughput as tt  # noqa: E402  (imports the package before torch)
import torch  # noqa: E402

STEM2 = {"encoder_stem_stride": 2}
# name -> (stage, model init_args, training points per shape (None: the bench default), kernel path, batch)
SETTINGS = {
    "stage1": [
        ("table1-medium", {}, {"surface": 2048, "sdf": 2048}, "reference", 16),
        ("table1-medium-fast", {}, {"surface": 1024, "sdf": 2048}, "bf16", 16),
        ("fast, 1,024 SDF samples", {}, {"surface": 1024, "sdf": 1024}, "bf16", 16),
        ("fast, 512 encoder points, 1,024 SDF", {}, {"surface": 512, "sdf": 1024}, "bf16", 16),
        ("fast, 512 encoder points, 512 SDF", {}, {"surface": 512, "sdf": 512}, "bf16", 16),
        ("fast, batch 32", {}, {"surface": 1024, "sdf": 2048}, "bf16", 32),
        ("512 / 1,024, batch 32", {}, {"surface": 512, "sdf": 1024}, "bf16", 32),
        ("512 / 1,024, U-Net 8 channels", {"unet_channels": 8}, {"surface": 512, "sdf": 1024}, "bf16", 16),
        ("512 / 1,024, U-Net depth 2", {"unet_max_depth": 2}, {"surface": 512, "sdf": 1024}, "bf16", 16),
        ("512 / 1,024, point width 16", {"width": 16}, {"surface": 512, "sdf": 1024}, "bf16", 16),
        ("512 / 1,024, SDF MLP 32 wide", {"mlp_hidden": 32}, {"surface": 512, "sdf": 1024}, "bf16", 16),
        ("512 / 1,024, U-Net 8 channels, depth 2", {"unet_channels": 8, "unet_max_depth": 2},
         {"surface": 512, "sdf": 1024}, "bf16", 16),
        ("512 / 1,024, U-Net 8 channels, batch 32", {"unet_channels": 8}, {"surface": 512, "sdf": 1024}, "bf16", 32),
    ],
    "stage2": [
        ("table1-medium", {}, None, "reference", 16),
        ("table1-medium-fast", STEM2, None, "fast", 16),
        ("fast, bfloat16", STEM2, None, "bf16", 16),
        ("fast, batch 32", STEM2, None, "fast", 32),
        ("fast, batch 32, bfloat16", STEM2, None, "bf16", 32),
        ("fast, ResNet width 1/8", {**STEM2, "encoder_width": 0.125}, None, "fast", 16),
        ("fast, batch 64", STEM2, None, "fast", 64),
        ("fast, batch 32, ResNet width 1/8", {**STEM2, "encoder_width": 0.125}, None, "fast", 32),
        ("fast, batch 32, ResNet width 1/8, bfloat16", {**STEM2, "encoder_width": 0.125}, None, "bf16", 32),
    ],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"shapes/s by wall clock, {args.threads} threads, best of {args.rounds} rounds; ratio against table1-medium")
    for stage, settings in SETTINGS.items():
        runners = []
        for _, model_args, points, path, batch in settings:
            model, data = tt.build(stage, batch=batch, model_args=model_args, points=points)
            runners.append(tt.Runner(model, data, path))
        steps = 3 if stage == "stage1" else 8
        best = [float("inf")] * len(runners)
        for _ in range(args.rounds):
            for i, runner in enumerate(runners):
                best[i] = min(best[i], runner.time(steps)[0])
        reference = settings[0][4] / best[0]
        for (name, *_, batch), seconds in zip(settings, best):
            print(f"  {stage}  {name:38s} {batch / seconds:7.1f}  x{batch / seconds / reference:.2f}", flush=True)


if __name__ == "__main__":
    main()
