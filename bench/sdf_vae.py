"""Benchmark: SDF-VAE (Stage 1) training steps per second on CPU at the CPU config's sizes.

    python bench/sdf_vae.py [--config conf/model/sdf_vae_cpu.yaml] [--batch 8] [--surface 512]
                            [--sdf 1024] [--steps 20] [--threads 0]

One step = encode, reparameterise, decode, truncated L1 + KL, backward, Adam. Batch size and
point counts default to those of conf/experiment/sdf_vae_parts_cpu.yaml. Prints steps/s by wall
clock and by process CPU time (on a shared machine the CPU figure is the stable one).
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

from radar2shape.models.sdf_vae import SDFVAE  # noqa: E402


def sphere_batch(batch: int, n_surface: int, n_sdf: int) -> dict:
    """Spheres of random radius: surface points and exact SDF samples (timing needs no dataset)."""
    gen = torch.Generator().manual_seed(0)
    radius = 0.15 + 0.3 * torch.rand(batch, 1, 1, generator=gen)
    directions = torch.nn.functional.normalize(torch.randn(batch, n_surface, 3, generator=gen), dim=-1)
    queries = torch.rand(batch, n_sdf, 3, generator=gen) * 1.1 - 0.55
    return {
        "surface_points": directions * radius,
        "sdf_points": queries,
        "sdf_values": queries.norm(dim=-1) - radius[..., 0],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=str(REPO / "conf/model/sdf_vae_cpu.yaml"))
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--surface", type=int, default=512)
    parser.add_argument("--sdf", type=int, default=1024)
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    init_args = yaml.safe_load(Path(args.config).read_text())["init_args"]
    model = SDFVAE(**init_args)
    optimizer = torch.optim.Adam(model.parameters(), lr=model.hparams.lr)
    batch = sphere_batch(args.batch, args.surface, args.sdf)

    def step() -> None:
        loss = model.losses(batch)["loss"]
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()

    for _ in range(3):  # warm-up: allocator and oneDNN primitive caches
        step()
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(args.steps):
        step()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    params = sum(p.numel() for p in model.parameters())
    print(
        f"sdf_vae train ({Path(args.config).name}, {params / 1e6:.2f} M params, batch {args.batch}, "
        f"{args.surface} surface + {args.sdf} sdf points, {torch.get_num_threads()} threads): "
        f"{args.steps / wall:.2f} steps/s wall, {args.steps / cpu:.2f} steps/s per CPU-second"
    )


if __name__ == "__main__":
    main()
