"""Where a Stage-1 SDF-VAE loses IoU: training shapes against test shapes, and the meshing grid.

    python scripts/stage1_fit_gap.py --run runs/table1-medium/radar2shape_stage1 \
        --train-shapes 100 --resolutions 64 128 --out reports/table1-medium/stage1-60-epochs/fit_gap.md

Scores the decoded posterior means (the Stage-1 ceiling of docs/metrics.md) with the test
protocol of the run's saved test config (same points, same scorer) on the test split and on a
fixed random subset of the training split, at each marching-cubes resolution. Reading it: a small
train-test gap with a low training IoU says the model underfits (capacity or schedule), not that
it memorises; equal IoU at a finer grid says the meshing is not what caps the score.
"""

from __future__ import annotations

import argparse
import importlib
from pathlib import Path

import numpy as np
import torch
from omegaconf import OmegaConf
from torch.utils.data import DataLoader

from radar2shape.atomic import write_text_atomic
from radar2shape.errors import UserInputError
from radar2shape.metrics.scoring import score_reconstruction
from radar2shape.models.radar_diffusion import load_stage1
from radar2shape.models.sdf_vae import SDFVAE
from radar2shape.reconstruction import Reconstruction

METRICS = ("iou", "chamfer_l2_x1e3", "fscore_1pct")


def datamodule_of(config_path: Path):
    """The run's test DataModule, built from its saved LightningCLI config."""
    section = OmegaConf.load(config_path).data
    module, name = section.class_path.rsplit(".", 1)
    datamodule = getattr(importlib.import_module(module), name)(**OmegaConf.to_container(section.init_args, resolve=True))
    datamodule.setup("test")
    return datamodule


def loaders(datamodule, train_shapes: int, seed: int = 0) -> dict[str, DataLoader]:
    """The test split, and ``train_shapes`` training records read with the test transform and points."""
    train = datamodule.records("train")
    dataset = datamodule.dataset_class(train, datamodule.manifest["labels"]["train"], datamodule.transform("test"),
                                       datamodule.points["test"], train=False, seed=seed, cache=False)
    picked = np.random.default_rng(seed).permutation(len(dataset))[:train_shapes]
    size = datamodule.hparams.batch_size
    return {"test": datamodule.test_dataloader(),
            "train": DataLoader(dataset, batch_size=size, sampler=[int(i) for i in picked])}


@torch.no_grad()
def score_split(model: SDFVAE, loader: DataLoader, resolutions: list[int]) -> tuple[dict[int, np.ndarray], np.ndarray]:
    """``{resolution: [shapes, len(METRICS)]}`` scores of the decoded posterior means, and ``[shapes, 2]``
    record index and class label of each row."""
    scores = {r: [] for r in resolutions}
    keys = []
    for batch in loader:
        mu, _ = model.encoder(batch["surface_points"])
        keys += [[int(i), int(c)] for i, c in zip(batch["index"], batch["label"])]
        for r in resolutions:
            for i, mesh in enumerate(model.extract_mesh(mu, r)):
                row = score_reconstruction(Reconstruction(mesh=mesh), batch["eval_points"][i].numpy(),
                                           batch["occ_points"][i].numpy(), batch["occ_inside"][i].numpy())
                scores[r].append([row[m] for m in METRICS])
    return {r: np.asarray(rows, dtype=np.float64) for r, rows in scores.items()}, np.asarray(keys, dtype=np.int64)


def per_shape_csv(scores: np.ndarray, keys: np.ndarray) -> str:
    """One row per shape with the column names of a report's Stage-1 ceiling (``ceiling_<metric>``), so
    ``scripts/paired_scores.py --metrics ceiling_iou ...`` pairs it with a report's per-shape scores."""
    lines = ["index,label," + ",".join(f"ceiling_{m}" for m in METRICS)]
    lines += [f"{i},{c}," + ",".join(repr(float(v)) for v in row) for (i, c), row in zip(keys, scores)]
    return "\n".join(lines) + "\n"


def report(ckpt: Path, results: dict[str, dict[int, np.ndarray]]) -> str:
    lines = [f"# Stage-1 fit gap: `{ckpt}`", "",
             "Posterior means decoded and scored with the run's test protocol (scripts/stage1_fit_gap.py); "
             "mean ± std over shapes.", "",
             "| split | shapes | marching-cubes grid | IoU ↑ | CD x10^3 ↓ | F@1% ↑ |", "|---|---|---|---|---|---|"]
    for split, by_resolution in results.items():
        for r, a in by_resolution.items():
            cells = [f"{np.nanmean(a[:, j]):.3f} ± {np.nanstd(a[:, j]):.3f}" for j in range(len(METRICS))]
            lines.append(f"| {split} | {len(a)} | {r}^3 | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", required=True, type=Path, help="a Stage-1 run folder of a sweep (fit/, and test/ when it was tested)")
    parser.add_argument("--ckpt", default="last.ckpt",
                        help="checkpoint file in the run's fit/version_0/checkpoints/ (default last.ckpt; e.g. best-val-iou.ckpt), "
                             "or the path of any Stage-1 or Radar2Shape checkpoint, scored on the run's data")
    parser.add_argument("--train-shapes", type=int, default=100)
    parser.add_argument("--resolutions", type=int, nargs="+", default=[64])
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--scores", type=Path, help="also write the test split's per-shape scores (first grid) to this CSV")
    args = parser.parse_args()
    ckpt = Path(args.ckpt) if Path(args.ckpt).is_file() else args.run / "fit/version_0/checkpoints" / args.ckpt
    config = args.run / "test/version_0/config.yaml"
    if not config.is_file():  # a grid may skip Stage 1's own test; the fit config holds the same DataModule
        config = args.run / "fit/version_0/config.yaml"
    for path in (ckpt, config):
        if not path.is_file():
            raise SystemExit(f"error: {path}: not found (expected a finished Stage-1 run of a sweep)")
    if args.train_shapes < 1 or any(r < 8 for r in args.resolutions):
        raise SystemExit("error: --train-shapes must be >= 1 and every --resolutions entry >= 8")
    try:
        model = load_stage1(ckpt).eval()
        datamodule = datamodule_of(config)
    except UserInputError as err:
        raise SystemExit(f"error: {err}") from None
    scored = {split: score_split(model, loader, args.resolutions)
              for split, loader in loaders(datamodule, args.train_shapes).items()}
    results = {split: by_resolution for split, (by_resolution, _) in scored.items()}
    if args.scores:
        by_resolution, keys = scored["test"]
        write_text_atomic(args.scores, per_shape_csv(by_resolution[args.resolutions[0]], keys))
    write_text_atomic(args.out, report(ckpt, results))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
