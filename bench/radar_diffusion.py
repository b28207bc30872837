"""Benchmark: Radar2Shape Stage-2 training throughput (shapes/s) on CPU, latents encoded vs cached.

    python bench/radar_diffusion.py [--stage1 conf/model/sdf_vae_medium.yaml]
        [--stage2 conf/model/radar_diffusion_medium.yaml] [--batch 16] [--surface 2048] [--steps 10] [--threads 0]

One step = Stage-2 diffusion loss (radar encoder + Transformer), backward, AdamW. "encoded": the
frozen Stage 1 encodes every batch's surface points into latents, as a naive loop would;
"cached": the latents come from the table RadarDiffusion fills once at fit start
(``collect_train_latents``), which is what training does. The ratio is the saving of the cache.
Radar on the default grid (32 aspects x 32 rolls x the model's frequencies), random values:
timing needs no dataset. Prints shapes/s by wall clock and per CPU-second.
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

from radar2shape.models.radar_diffusion import RadarDiffusion  # noqa: E402


def build(stage1_file: Path, stage2_file: Path) -> RadarDiffusion:
    """Stage 2 of ``stage2_file`` over an untrained Stage 1 of ``stage1_file`` (sizes are what cost)."""
    stage1 = yaml.safe_load(stage1_file.read_text())["init_args"]
    stage2 = {k: v for k, v in yaml.safe_load(stage2_file.read_text())["init_args"].items() if k != "stage1_ckpt"}
    model = RadarDiffusion(stage1_hparams=stage1, **stage2)
    model.standardiser.ready.fill_(True)
    return model


def time_steps(model: RadarDiffusion, batch: dict, steps: int) -> tuple[float, float]:
    """(wall, CPU) seconds of ``steps`` training steps after 2 warm-up steps."""
    optimizer = torch.optim.AdamW([p for p in model.parameters() if p.requires_grad], lr=1e-3)

    def step() -> None:
        loss = model.diffusion_loss(batch)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()

    for _ in range(2):
        step()
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(steps):
        step()
    return time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stage1", type=Path, default=REPO / "conf/model/sdf_vae_medium.yaml")
    parser.add_argument("--stage2", type=Path, default=REPO / "conf/model/radar_diffusion_medium.yaml")
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--surface", type=int, default=2048)
    parser.add_argument("--steps", type=int, default=10)
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    model = build(args.stage1, args.stage2).train()
    num_freq = int(model.hparams.num_freq)
    batch = {
        "radar": torch.randn(args.batch, 32, 32, num_freq),
        "radar_mask": torch.ones(args.batch, 32, 32),
        "surface_points": torch.rand(args.batch, args.surface, 3) - 0.5,
        "index": torch.arange(args.batch),
    }
    results = {}
    model._train_latents = {}
    results["encoded"] = time_steps(model, batch, args.steps)
    with torch.no_grad():
        model._train_latents = dict(enumerate(model.stage1.encode(batch["surface_points"])[0]))
    results["cached"] = time_steps(model, batch, args.steps)
    trainable = sum(p.numel() for p in model.parameters() if p.requires_grad)
    print(f"radar_diffusion train ({args.stage2.name} on {args.stage1.name}, {trainable / 1e6:.2f} M trainable, "
          f"batch {args.batch}, radar 32x32x{num_freq}, {torch.get_num_threads()} threads)")
    for name, (wall, cpu) in results.items():
        shapes = args.steps * args.batch
        print(f"  latents {name:8s}: {shapes / wall:7.1f} shapes/s wall, {shapes / cpu:7.1f} shapes per CPU-second")
    ratio = results["encoded"][0] / results["cached"][0]
    print(f"  cache speed-up: {ratio:.2f}x (wall)")


if __name__ == "__main__":
    main()
