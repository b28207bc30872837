"""The README's picture: objects the shipped model never saw, their radar, and what it reconstructs.

    python scripts/overview_figure.py [--model parts] [--data data/parts_unseen] [--out docs/figures/overview.png]
    python scripts/overview_figure.py --model real --data data/real --classes airliner fighter ship \
        --out docs/figures/overview_real.png

Rows: test shapes of ``--data`` (a build of conf/data/parts_unseen.yaml, which ``make demo``
makes); columns: the object, its simulated radar (dB over aspect x roll at the middle frequency),
and the shipped model's (``--model``: ``parts`` or ``real``) reconstruction with its IoU. The shapes are picked by class (``--classes``),
the first test shape of each, never by score.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="parts", help="shipped model name (radar2shape.pretrained.SHIPPED_MODELS)")
    parser.add_argument("--data", type=Path, default=ROOT / "data/parts_unseen")
    parser.add_argument("--out", type=Path, default=ROOT / "docs/figures/overview.png")
    parser.add_argument("--classes", nargs="+", default=["airplane", "car", "chair"])
    return parser.parse_args(argv)


def first_of_each_class(records, classes: list[str]) -> list[int]:
    found = {}
    for i in range(len(records)):
        name = str(records[i]["class_name"])
        if name in classes and name not in found:
            found[name] = i
    missing = sorted(set(classes) - set(found))
    if missing:
        from radar2shape.errors import UserInputError

        raise UserInputError(f"--classes: no test shape of class {missing} in the data")
    return [found[c] for c in classes]


def main(argv=None) -> int:
    args = parse_args(argv)
    import torch
    from matplotlib.figure import Figure

    from data_modules.datamodules import ShapeDataModule
    from radar2shape.atomic import atomic_path
    from radar2shape.commands.reconstruct import model_batch
    from radar2shape.geometry.query import sample_surface
    from radar2shape.metrics.render import depth_image
    from radar2shape.metrics.scoring import score_reconstruction
    from radar2shape.pretrained import load_model, shipped_checkpoint
    from radar2shape.radar.measured import GridInput

    torch.set_num_threads(2)
    model = load_model(shipped_checkpoint(args.model))
    spec = model.radar_spec
    records = ShapeDataModule(root=str(args.data)).records("test")
    picked = first_of_each_class(records, args.classes)
    fig = Figure(figsize=(9.0, 3.0 * len(picked)), layout="constrained")
    axes = fig.subplots(len(picked), 3, squeeze=False)
    roll, aspect = np.degrees(spec.grid.roll_rad), np.degrees(spec.grid.aspect_rad)
    for row, index in enumerate(picked):
        record = records[index]
        db = spec.to_db(record["radar"])
        batch = model_batch(spec, GridInput(db, np.ones(db.shape[:2], bool), np.ones(db.shape[2], bool), 1.0))
        recon = model.reconstruct(batch)[0]
        score = score_reconstruction(recon, record["eval_points"], record["occ_points"], record["occ_inside"])
        truth = record["eval_points"]
        predicted = sample_surface(recon.mesh, 20_000, 0)[0] if recon.mesh is not None and len(recon.mesh.faces) else truth[:0]
        axes[row, 0].imshow(depth_image(truth, -55, 25), cmap="viridis", vmin=-0.6, vmax=0.6)
        axes[row, 0].set_title(f"{record['class_name']} (never seen)", fontsize=10)
        axes[row, 1].imshow(db[:, :, db.shape[2] // 2], cmap="magma", aspect="auto",
                            extent=(roll[0], roll[-1], aspect[-1], aspect[0]))
        axes[row, 1].set(xlabel="roll (deg)", ylabel="aspect (deg)")
        axes[row, 1].set_title(f"its radar at {spec.grid.freq_hz[db.shape[2] // 2] / 1e9:.1f} GHz (dBsm)", fontsize=10)
        axes[row, 2].imshow(depth_image(predicted, -55, 25), cmap="viridis", vmin=-0.6, vmax=0.6)
        axes[row, 2].set_title(f"reconstruction from the radar, IoU {score['iou']:.2f}", fontsize=10)
        for col in (0, 2):
            axes[row, col].set(xticks=[], yticks=[])
    with atomic_path(args.out) as temp:
        fig.savefig(temp, dpi=80, format="png")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
