"""How much of a Stage-1 ceiling the encoder loses: decode the posterior means, then latents fitted to each shape.

    python scripts/latent_refinement.py --ckpt src/radar2shape/weights/radar2shape_real.ckpt \
        --data data/real --split test --out reports/real/latent_refinement.md

The Stage-1 ceiling decodes the encoder's posterior mean of each shape. Here the decoder is frozen
and each shape's latent ``h [L, Z]`` is moved by Adam, from that mean, to lower the truncated L1
loss on the record's stored SDF samples (the training loss, on points the encoder never sees);
both latents are meshed on the test grid and scored on the record's occupancy and surface points.
If the fitted latents score much higher, the decoder can express the shapes and the encoder (an
amortised guess of the latent) is what caps the ceiling; if not, the decoder is.

``--ckpt`` is a Stage-1 checkpoint or a Radar2Shape checkpoint holding one. Writes OUT (means per
class, the latent's move relative to its norm), OUT with ``.csv`` (one row per shape) and with
``.png`` (slices of the objects that gain and lose most). Bad input is one ``error:`` line.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
from pathlib import Path

import numpy as np
import torch

from data_modules.manifest import read_manifest
from data_modules.records import read_record, record_path
from radar2shape.atomic import write_text_atomic
from radar2shape.errors import UserInputError
from radar2shape.metrics.scoring import score_reconstruction
from radar2shape.models.radar_diffusion import load_stage1
from radar2shape.models.sdf_vae import SDFVAE, truncated_l1
from radar2shape.reconstruction import Reconstruction

SURFACE_POINTS = 2048  # the encoder input of the test protocol (conf/data/module/*.yaml, points.test)


def refine_latents(model: SDFVAE, h: torch.Tensor, points: torch.Tensor, values: torch.Tensor, steps: int,
                   lr: float = 1e-2, batch_points: int = 4096, seed: int = 0) -> torch.Tensor:
    """Latents ``[B, L, Z]`` fitted by Adam to SDF samples ``points [B, P, 3]``, ``values [B, P]``.

    The decoder is frozen; each step reads ``batch_points`` random samples of every shape. The
    loss is a mean over shapes, so each shape's latent moves as if it were fitted alone."""
    generator = torch.Generator().manual_seed(seed)
    truncation = model.hparams.truncation
    h = h.detach().clone().requires_grad_(True)
    optimizer = torch.optim.Adam([h], lr=lr)
    rows = torch.arange(points.shape[0])[:, None]
    for _ in range(steps):
        pick = torch.randint(0, points.shape[1], (points.shape[0], min(batch_points, points.shape[1])), generator=generator)
        loss = truncated_l1(model.decode_sdf(h, points[rows, pick]), values[rows, pick], truncation) * points.shape[0]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    return h.detach()


@torch.no_grad()
def per_shape_l1(model: SDFVAE, h: torch.Tensor, points: torch.Tensor, values: torch.Tensor) -> list[float]:
    """The training loss of each shape's latent on all its SDF samples."""
    return [truncated_l1(model.decode_sdf(h[i:i + 1], points[i:i + 1]), values[i:i + 1], model.hparams.truncation).item()
            for i in range(len(h))]


def score(model: SDFVAE, h: torch.Tensor, record: dict, resolution: int) -> dict[str, float]:
    with torch.no_grad():
        mesh = model.extract_mesh(h[None], resolution)[0]
    return score_reconstruction(Reconstruction(mesh=mesh), record["eval_points"], record["occ_points"], record["occ_inside"])


def measure(model: SDFVAE, root: Path, split: str, indices: list[int], ids: list[str], args) -> tuple[list[dict], dict]:
    """One row per record (scores and SDF loss of its encoded and its fitted latent), and the latents by record id."""
    rows, latents = [], {}
    for start in range(0, len(ids), args.batch):
        chunk = ids[start:start + args.batch]
        records = [read_record(record_path(root, split, i)) for i in chunk]
        surface = torch.from_numpy(np.stack([r["surface_points"][:SURFACE_POINTS] for r in records]))
        points = torch.from_numpy(np.stack([r["sdf_points"] for r in records]))
        values = torch.from_numpy(np.stack([r["sdf_values"] for r in records]))
        with torch.no_grad():
            mu, _ = model.encode(surface)
        fitted = refine_latents(model, mu, points, values, args.steps, args.lr, seed=start)
        l1_before, l1_after = (per_shape_l1(model, h, points, values) for h in (mu, fitted))
        for i, (record_id, record) in enumerate(zip(chunk, records)):
            before, after = score(model, mu[i], record, args.resolution), score(model, fitted[i], record, args.resolution)
            rows.append({"index": indices[start + i], "record_id": record_id, "label": int(record["label"]),
                         "sdf_l1_encoded": l1_before[i], "sdf_l1_fitted": l1_after[i],
                         "iou_encoded": before["iou"], "iou_fitted": after["iou"],
                         "fscore_1pct_encoded": before["fscore_1pct"], "fscore_1pct_fitted": after["fscore_1pct"],
                         "latent_move": float((fitted[i] - mu[i]).norm() / mu[i].norm().clamp(min=1e-12))})
            latents[record_id] = (mu[i], fitted[i])
        print(f"\r{len(rows)}/{len(ids)} shapes", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    return rows, latents


def draw(model: SDFVAE, root: Path, split: str, rows: list[dict], latents: dict, out: Path, per_side: int = 3) -> None:
    """Slices through the objects that gain most and lose most: truth, encoded, fitted (inside in colour).

    Each object is cut by the horizontal plane and the vertical (xz) plane through the median of its
    surface samples, and each cut is labelled inside/outside by the record's mesh and by both decoded SDFs."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import trimesh

    from radar2shape.geometry.query import contains

    ranked = sorted((r for r in rows if not math.isnan(r["iou_fitted"] - r["iou_encoded"])),
                    key=lambda r: r["iou_fitted"] - r["iou_encoded"])
    best = ranked[::-1][:per_side]
    picked = best + [r for r in ranked[:per_side][::-1] if r not in best]
    bound, n = float(model.hparams.bound), 160
    axis = np.linspace(-bound, bound, n, dtype=np.float32)
    u, v = np.meshgrid(axis, axis, indexing="xy")
    fig, axes = plt.subplots(len(picked), 6, figsize=(13, 2.3 * len(picked)), squeeze=False)
    for row_axes, row in zip(axes, picked):
        record = read_record(record_path(root, split, row["record_id"]), ["vertices", "faces", "surface_points"])
        mesh = trimesh.Trimesh(record["vertices"], record["faces"], process=False)
        centre = np.median(record["surface_points"], axis=0)
        cuts = {"xy": np.stack([u.ravel(), v.ravel(), np.full(u.size, centre[2])], 1),
                "xz": np.stack([u.ravel(), np.full(u.size, centre[1]), v.ravel()], 1)}
        panels = []
        for plane, points in cuts.items():
            query = torch.from_numpy(points.astype(np.float32))[None]
            with torch.no_grad():
                encoded, fitted = (model.surface_sdf(model.decoder.decode_planes(h[None]), query)[0].numpy() < 0
                                   for h in latents[row["record_id"]])
            panels += [(contains(mesh, points), f"truth, {plane}"), (encoded, f"encoded {row['iou_encoded']:.2f}"),
                       (fitted, f"fitted {row['iou_fitted']:.2f}")]
        for ax, (inside, title) in zip(row_axes, panels):
            ax.imshow(inside.reshape(n, n), origin="lower", extent=(-bound, bound, -bound, bound), cmap="Blues")
            ax.set_title(title, fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
        row_axes[0].set_ylabel(row["record_id"].split("__")[1][:18], fontsize=8)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    plt.close(fig)


def mean(values) -> float:
    values = [v for v in values if not math.isnan(v)]
    return sum(values) / len(values) if values else math.nan


def markdown(args, rows: list[dict], classes: list[str]) -> str:
    columns = [("iou_encoded", "IoU, encoded"), ("iou_fitted", "IoU, fitted"), ("fscore_1pct_encoded", "F@1%, encoded"),
               ("fscore_1pct_fitted", "F@1%, fitted"), ("sdf_l1_encoded", "SDF L1, encoded"),
               ("sdf_l1_fitted", "SDF L1, fitted"), ("latent_move", "latent move")]
    gain = np.array([r["iou_fitted"] - r["iou_encoded"] for r in rows], dtype=float)
    gain = gain[np.isfinite(gain)]
    lines = [f"# Stage-1 latents: encoded against fitted, `{args.data}` {args.split} split", "",
             f"Made by `scripts/latent_refinement.py` with `{args.ckpt}`: the decoder frozen, each shape's latent moved "
             f"from the encoder's posterior mean by {args.steps} Adam steps (learning rate {args.lr:g}) on the record's "
             f"SDF samples, both meshed at {args.resolution}^3 and scored on the record's occupancy and surface points. "
             "Latent move: |fitted - encoded| / |encoded|. Means per class:", "",
             "| class (shapes) | " + " | ".join(t for _, t in columns) + " |", "|---" * (len(columns) + 1) + "|"]
    groups: dict[str, list[dict]] = {}
    for row in rows:
        groups.setdefault(classes[row["label"]] if row["label"] < len(classes) else str(row["label"]), []).append(row)
    for name, members in [*sorted(groups.items()), ("**all**", rows)]:
        lines.append(f"| {name} ({len(members)}) | " + " | ".join(f"{mean([m[c] for m in members]):.4g}" for c, _ in columns) + " |")
    lines += ["", f"IoU gain of the fitted latents: {gain.mean():+.3f} ± {gain.std(ddof=1) / math.sqrt(len(gain)):.3f} "
              f"(mean ± standard error over {len(gain)} shapes); higher on {int((gain > 0).sum())} of them."]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ckpt", required=True, type=Path, help="a Stage-1 checkpoint or a Radar2Shape checkpoint holding one")
    parser.add_argument("--data", required=True, type=Path)
    parser.add_argument("--split", default="test")
    parser.add_argument("--shapes", type=int, default=0, help="a fixed random subset of this many shapes (0: all)")
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--lr", type=float, default=1e-2)
    parser.add_argument("--batch", type=int, default=8, help="shapes fitted together")
    parser.add_argument("--resolution", type=int, default=64, help="marching-cubes grid of the scores")
    parser.add_argument("--out", required=True, type=Path)
    args = parser.parse_args()
    try:
        if args.steps < 1 or args.lr <= 0 or args.batch < 1 or args.resolution < 8 or args.shapes < 0:
            raise UserInputError("--steps, --batch must be >= 1, --lr > 0, --resolution >= 8, --shapes >= 0")
        model = load_stage1(args.ckpt).eval().requires_grad_(False)
        manifest = read_manifest(args.data)
        ids = list(manifest["splits"].get(args.split, []))
        if not ids:
            raise UserInputError(f"{args.data}: split {args.split!r} has no records")
        indices = list(range(len(ids)))
        if args.shapes:
            indices = sorted(int(i) for i in np.random.default_rng(0).permutation(len(ids))[:args.shapes])
        rows, latents = measure(model, args.data, args.split, indices, [ids[i] for i in indices], args)
    except UserInputError as err:
        raise SystemExit(f"error: {err}") from None
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(args.out.with_suffix(".csv"), table.getvalue())
    figure = args.out.with_suffix(".png")
    draw(model, args.data, args.split, rows, latents, figure)
    write_text_atomic(args.out, markdown(args, rows, manifest["classes"]) + f"\n![slices]({figure.name})\n")
    print(f"wrote {args.out}, {args.out.with_suffix('.csv')} and {figure}")


if __name__ == "__main__":
    main()
