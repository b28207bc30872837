"""Benchmark: LIST training throughput (shapes/s) on CPU against the points sampled per step.

    python bench/list_net.py [--model conf/model/list_medium.yaml] [--batch 16] [--steps 3] [--threads 1]

One step = LIST's losses (radar encoder, coarse cloud, local SDF queries), backward, Adam, on a
batch of random radar on the default grid and random points: timing needs no dataset. Two point
budgets per shape: the medium DataModule's (4,096 SDF / 2,048 surface points) and the halved one
the medium grid gives the LIST rows (2,048 / 1,024, as its Stage-1 rows). The step cost falls
faster than the point count (the per-point activations stop fitting in cache), so the ratio is
printed in the same run.
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

from baselines.list_net import LIST  # noqa: E402

BUDGETS = {"module (4096 sdf / 2048 surface)": (4096, 2048), "grid (2048 sdf / 1024 surface)": (2048, 1024)}


def seconds_per_step(model: LIST, batch: dict, steps: int) -> float:
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, default=REPO / "conf/model/list_medium.yaml")
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--steps", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1, help="torch threads (the grid's lanes use 1)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    hparams = yaml.safe_load(args.model.read_text())["init_args"]
    model = LIST(**hparams).train()
    num_freq = int(hparams["num_freq"])
    print(f"LIST train ({args.model.name}, batch {args.batch}, radar 32x32x{num_freq}, {args.threads} threads)")
    timings = {}
    for name, (n_sdf, n_surface) in BUDGETS.items():
        batch = {
            "radar": torch.randn(args.batch, 32, 32, num_freq),
            "radar_mask": torch.ones(args.batch, 32, 32, dtype=torch.bool),
            "sdf_points": torch.rand(args.batch, n_sdf, 3) - 0.5,
            "sdf_values": torch.randn(args.batch, n_sdf) * 0.05,
            "surface_points": torch.rand(args.batch, n_surface, 3) - 0.5,
        }
        timings[name] = seconds_per_step(model, batch, args.steps)
        print(f"  points {name}: {timings[name]:.3f} s/step, {args.batch / timings[name]:.1f} shapes/s")
    before, after = timings.values()
    print(f"  speed-up of the grid's budget: {before / after:.2f}x")


if __name__ == "__main__":
    main()
