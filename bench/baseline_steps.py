"""Benchmark: training throughput (shapes/s) of the single-stage baselines against the points per step.

    python bench/baseline_steps.py [--model conf/model/list_medium.yaml ...] [--batch 16] [--steps 3] [--threads 1]

One step = the model's losses, backward, Adam, on a batch of random radar on the default grid and
random points: timing needs no dataset. Two point budgets per shape: the medium DataModule's
(4,096 SDF / 2,048 surface points) and the halved one the medium grid gives the LIST rows (2,048 /
1,024, as its Stage-1 rows). For LIST the step cost falls faster than the point count (its
per-point local features stop fitting in cache), so the ratio is printed in the same run.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

import torch  # noqa: E402
import yaml  # noqa: E402
from lightning.pytorch.cli import instantiate_class  # noqa: E402

MODELS = [REPO / "conf/model/list_medium.yaml", REPO / "conf/model/tmnet_medium.yaml"]

BUDGETS = {"module (4096 sdf / 2048 surface)": (4096, 2048), "halved (2048 sdf / 1024 surface)": (2048, 1024)}


def seconds_per_step(model: torch.nn.Module, batch: dict, steps: int) -> float:
    """Wall seconds of one training step, mean of ``steps`` after one warm-up step."""
    optimizer = torch.optim.Adam(model.parameters(), lr=1e-3)

    def step() -> None:
        loss = model.losses(batch)["loss"]
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()

    step()
    start = time.perf_counter()
    for _ in range(steps):
        step()
    return (time.perf_counter() - start) / steps


def bench(config: Path, batch_size: int, steps: int, threads: int) -> None:
    torch.manual_seed(0)
    model = instantiate_class((), yaml.safe_load(config.read_text())).train()
    num_freq = int(model.hparams.num_freq)
    print(f"{type(model).__name__} train ({config.name}, batch {batch_size}, radar 32x32x{num_freq}, {threads} threads)")
    timings = {}
    for name, (n_sdf, n_surface) in BUDGETS.items():
        batch = {
            "radar": torch.randn(batch_size, 32, 32, num_freq),
            "radar_mask": torch.ones(batch_size, 32, 32, dtype=torch.bool),
            "sdf_points": torch.rand(batch_size, n_sdf, 3) - 0.5,
            "sdf_values": torch.randn(batch_size, n_sdf) * 0.05,
            "surface_points": torch.rand(batch_size, n_surface, 3) - 0.5,
            "surface_normals": torch.nn.functional.normalize(torch.randn(batch_size, n_surface, 3), dim=-1),
        }
        timings[name] = seconds_per_step(model, batch, steps)
        print(f"  points {name}: {timings[name]:.3f} s/step, {batch_size / timings[name]:.1f} shapes/s")
    before, after = timings.values()
    print(f"  speed-up at half the points: {before / after:.2f}x")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, nargs="+", default=MODELS, help="model configs (default LIST, TMNet medium)")
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1, help="torch threads (the grid's lanes use 1)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    for config in args.model:
        bench(config, args.batch, args.steps, args.threads)


if __name__ == "__main__":
    main()
