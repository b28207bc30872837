"""Figure: what each latent level holds, by swapping the coarse levels of two shapes' latents.

    python scripts/latent_swap.py --ckpt runs/.../last.ckpt --data data/parts_tiny \
        --split test --pairs 0:1 2:3 --out reports/figures/latent_swap.png [--resolution 64]

For each pair (A, B) a row shows the decoded meshes of the latents that take levels ``< k``
from B and levels ``>= k`` from A, for k = 0 (A itself) .. L (B itself). If the hierarchy works,
the coarse levels carry the overall shape and the fine levels the detail, so the middle columns
look like B's outline with A's detail. Latents are posterior means of each record's surface
points. Meshes are drawn as depth images of surface samples (matplotlib Agg, no display).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from data_modules.datasets import RecordSet
from data_modules.manifest import read_manifest
from radar2shape.errors import UserInputError
from radar2shape.geometry.query import sample_surface
from radar2shape.metrics.render import depth_image
from radar2shape.models.sdf_vae import SDFVAE


def swapped_latents(h_a: torch.Tensor, h_b: torch.Tensor) -> torch.Tensor:
    """``[L + 1, L, Z]``: row k takes levels ``< k`` from ``h_b`` and the rest from ``h_a``."""
    n_levels = h_a.shape[0]
    rows = [torch.cat([h_b[:k], h_a[k:]]) for k in range(n_levels + 1)]
    return torch.stack(rows)


def level_range(start: int, stop: int) -> str:
    return f"level {start}" if stop - start == 1 else f"levels {start}-{stop - 1}"


def column_titles(n_levels: int) -> list[str]:
    titles = ["A"]
    titles += [f"B {level_range(0, k)}\n+ A {level_range(k, n_levels)}" for k in range(1, n_levels)]
    return titles + ["B"]


def parse_pairs(pairs: list[str]) -> list[tuple[int, int]]:
    try:
        return [tuple(int(i) for i in p.split(":")) for p in pairs]  # type: ignore[misc]
    except ValueError as err:
        raise UserInputError(f"--pairs takes A:B record indices such as 0:1, got {pairs}") from err


def encode_records(model: SDFVAE, records: RecordSet, indices: list[int], n_points: int) -> dict[int, torch.Tensor]:
    """Posterior mean ``[L, Z]`` of each record's surface points (first ``n_points``)."""
    latents = {}
    for i in sorted(set(indices)):
        if not 0 <= i < len(records):
            raise UserInputError(f"record index {i} out of range: split '{records.split}' has {len(records)} records")
        points = torch.as_tensor(records[i]["surface_points"][:n_points], dtype=torch.float32, device=model.device)
        latents[i] = model.encode(points[None])[0][0]
    return latents


def plot_rows(rows: list[list], titles: list[str], row_labels: list[str], out: Path, n_points: int) -> Path:
    """Grid of depth images: one row per pair, one column per swap."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(2.0 * len(titles), 2.1 * len(rows) + 0.4))
    axes = fig.subplots(len(rows), len(titles), squeeze=False)
    for r, meshes in enumerate(rows):
        for c, mesh in enumerate(meshes):
            points = sample_surface(mesh, n_points, seed=0)[0] if len(mesh.faces) else np.zeros((0, 3))
            ax = axes[r, c]
            ax.imshow(depth_image(points, -55.0, 25.0), cmap="viridis", vmin=-0.6, vmax=0.6)
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(titles[c], fontsize=8)
            if c == 0:
                ax.set_ylabel(row_labels[r], fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    return out


@torch.no_grad()
def latent_swap_figure(ckpt: str, data: str, split: str, pairs: list[tuple[int, int]], out: Path,
                       resolution: int, n_points: int = 2048) -> Path:
    model = SDFVAE.load_from_checkpoint(ckpt, map_location="cpu").eval()
    manifest = read_manifest(Path(data))
    if split not in manifest["splits"]:
        raise UserInputError(f"{data}: no split '{split}' (has {sorted(manifest['splits'])})")
    records = RecordSet(data, split, manifest["splits"][split])
    latents = encode_records(model, records, [i for pair in pairs for i in pair], n_points)
    rows = [model.extract_mesh(swapped_latents(latents[a], latents[b]), resolution) for a, b in pairs]
    labels = [f"A = #{a}, B = #{b}" for a, b in pairs]
    return plot_rows(rows, column_titles(model.n_levels), labels, out, n_points)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ckpt", required=True, help="SDFVAE checkpoint")
    parser.add_argument("--data", required=True, help="built dataset folder")
    parser.add_argument("--split", default="test")
    parser.add_argument("--pairs", nargs="+", default=["0:1"], help="record index pairs A:B")
    parser.add_argument("--out", default="reports/figures/latent_swap.png")
    parser.add_argument("--resolution", type=int, default=64, help="marching-cubes grid size")
    args = parser.parse_args()
    path = latent_swap_figure(args.ckpt, args.data, args.split, parse_pairs(args.pairs), Path(args.out), args.resolution)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
