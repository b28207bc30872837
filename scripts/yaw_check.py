"""Does a model reconstruct an object turned about its up axis as well as the object unturned?

    python scripts/yaw_check.py --ckpt RUN/checkpoints/last.ckpt --data data/real \
        --classes airliner "business jet" "light aircraft" fighter helicopter --yaw-deg 37 \
        --out reports/table1-real/yaw_check.md

For each test record of the named classes, as a user would: the record's watertight mesh is turned
by each yaw about z, put in the normalised frame (centred, longest side 1, as ``radar2shape
simulate`` does at ``--size-m 1``), simulated with physical optics on the model's radar grid,
reconstructed by the model from the full response, and scored (IoU, Chamfer, F-score) against that
turned mesh. Yaw 0 goes through the same path, so the difference is the cost of the turn alone. A
yaw that is not a multiple of the roll step is not a shift of any training response: the model has
to generalise. Writes a Markdown table (per object and the mean, paired differences with their
standard error).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ckpt", type=Path, required=True, help="a RadarDiffusion checkpoint (a fit's last.ckpt)")
    parser.add_argument("--data", type=Path, required=True, help="the dataset whose test split is turned")
    parser.add_argument("--classes", nargs="+", required=True)
    parser.add_argument("--yaw-deg", type=float, nargs="+", default=[37.0])
    parser.add_argument("--whole-steps", action="store_true",
                        help="a canonical-heading model places its mesh at the nearest whole roll step only")
    parser.add_argument("--out", type=Path, required=True)
    return parser.parse_args(argv)


def turned(mesh, yaw_deg: float):
    """``mesh`` turned about z by ``yaw_deg``, then normalised (bbox centred, longest side 1)."""
    import trimesh

    from radar2shape.geometry.normalise import normalise

    out = mesh.copy()
    out.apply_transform(trimesh.transformations.rotation_matrix(math.radians(yaw_deg), (0, 0, 1)))
    return normalise(out)[0]


def scorer(target):
    """A function scoring a :class:`Reconstruction` against the mesh ``target`` (its points sampled once,
    with the evaluator's counts)."""
    from radar2shape.geometry.query import contains, sample_surface
    from radar2shape.metrics.functional import occupancy_points
    from radar2shape.metrics.scoring import score_reconstruction

    gt_points, _ = sample_surface(target, 30_000, 1)
    occ = occupancy_points(100_000, 2, [target.bounds])
    inside = contains(target, occ)
    return lambda recon: score_reconstruction(recon, gt_points, occ, inside, 30_000)


def score_turn(model, record, yaw_deg: float) -> dict[str, float]:
    import trimesh

    from radar2shape.commands.reconstruct import model_batch
    from radar2shape.radar import simulate
    from radar2shape.radar.measured import GridInput

    spec = model.radar_spec
    mesh = turned(trimesh.Trimesh(record["vertices"], record["faces"], process=False), yaw_deg)
    response = simulate(mesh, spec.grid.aspect_rad, spec.grid.roll_rad, spec.grid.freq_hz)
    db = spec.to_db(response)
    batch = model_batch(spec, GridInput(db, np.ones(db.shape[:2], bool), np.ones(db.shape[2], bool), 1.0))
    return scorer(mesh)(model.reconstruct(batch)[0])


def records_of(data: Path, classes: list[str], split: str = "test"):
    """``(records, [(index, class name), ...])`` of the ``split`` records of ``classes`` in ``data``
    (the turned-object scripts share it); no such record is one error line, exit status 2."""
    from data_modules.datamodules import ShapeDataModule

    dm = ShapeDataModule(root=str(data))
    records, labels = dm.records(split), dm.manifest["labels"][split]
    wanted = {dm.class_names.index(c) for c in classes if c in dm.class_names}
    picked = [(i, dm.class_names[label]) for i, label in enumerate(labels) if label in wanted]
    if not picked:
        print(f"error: --classes: no {split} record of {classes} in {data}", file=sys.stderr)
        raise SystemExit(2)
    return records, picked


def paired(diff: np.ndarray) -> str:
    """``mean ± standard error`` of paired differences."""
    se = diff.std(ddof=1) / math.sqrt(len(diff)) if len(diff) > 1 else float("nan")
    return f"{diff.mean():+.3f} ± {se:.3f}"


def main(argv=None) -> int:
    args = parse_args(argv)
    import torch

    from radar2shape.atomic import write_text_atomic
    from radar2shape.pretrained import load_model

    torch.set_num_threads(2)
    model = load_model(args.ckpt)
    if args.whole_steps:
        model.hparams.refine_heading = False
    records, picked = records_of(args.data, args.classes)
    yaws = [0.0, *args.yaw_deg]
    start = time.perf_counter()
    rows = []
    for i, name in picked:
        record = records[i]
        scores = [score_turn(model, record, yaw) for yaw in yaws]
        rows.append((records.record_ids[i], name, scores))
        print(f"{records.record_ids[i]}: " + ", ".join(f"yaw {y:g}: IoU {s['iou']:.3f}" for y, s in zip(yaws, scores)))
    lines = [f"# Turned objects: {args.ckpt}", "",
             f"Test objects of {', '.join(args.classes)} in `{args.data}`, turned about z, simulated (PO) on the "
             "model's grid with every cell observed, reconstructed and scored against the turned mesh "
             f"(`scripts/yaw_check.py`{' --whole-steps' if args.whole_steps else ''}, "
             f"{time.perf_counter() - start:.0f} s).", "",
             "| object | class | " + " | ".join(f"IoU at {y:g} deg" for y in yaws) + " |", "|---" * (len(yaws) + 2) + "|"]
    lines += [f"| {rid} | {name} | " + " | ".join(f"{s['iou']:.3f}" for s in scores) + " |" for rid, name, scores in rows]
    iou = np.array([[s["iou"] for s in scores] for _, _, scores in rows])
    lines += ["| mean | | " + " | ".join(f"{m:.3f}" for m in iou.mean(axis=0)) + " |", ""]
    for k, yaw in enumerate(yaws[1:], start=1):
        lines.append(f"Yaw {yaw:g} deg minus unturned, paired over {len(iou)} objects: IoU {paired(iou[:, k] - iou[:, 0])}.")
    write_text_atomic(args.out, "\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
