"""Can an object's heading be read from its radar, given its shape in the canonical frame?

    python scripts/heading_from_radar.py --ckpt runs/table1-real-stage1-noaug/radar2shape_stage1_noaug/fit/version_0/checkpoints/last.ckpt \
        --data data/real --out reports/table1-real-stage1-noaug/heading_from_radar.md

A model that reconstructs every object in its canonical heading (x along the fuselage) must also
say how the observed object is turned. Turning about z by whole roll steps and mirroring through
the xz plane only re-index the response along roll (``data_modules.augment``), so the heading can
be searched: simulate the reconstruction once, re-index its response for each of the 2R candidate
turns, and keep the one whose dB map correlates best with the observed response. Correlation, not
a residual: it ignores a level offset (size, calibration).

For each test record (optionally only some classes): the canonical reconstruction is the Stage-1
decoding of the record's own surface points (what a canonical Stage 2 returns at best); the
observed object is the record turned by a random whole number of roll steps and mirrored half the
time. Scored against the turned object: the reconstruction placed at the estimated turn, at the
true turn (oracle), and left in the canonical heading (a model that ignores the heading); and the
same search run with the record's own response in place of the reconstruction's (a check: it must
find the true turn or a symmetric equivalent). Two correlations: the full ``[A, R, F]`` dB map,
and the band-averaged power per (aspect, roll) cell, which leaves out the fine interference
pattern in frequency that a smooth reconstruction does not reproduce; and the full map's turn
refined between steps (``refined_shift``), which costs a little where the true turn is whole.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from radar2shape.radar.heading import estimate_turn, power_db, refined_shift, turn_rotation

def search(observed: np.ndarray, candidate: np.ndarray, roll_rad: np.ndarray,
           band_average: bool) -> tuple[tuple[int, bool], np.ndarray]:
    """The turn of the complex response ``candidate`` closest to the complex ``observed`` (dB maps),
    and the correlation of every turn."""
    return estimate_turn(power_db(observed), power_db(candidate), roll_rad, band_average=band_average)


def placed(mesh_arrays: dict, turn: tuple[float, bool], roll_rad: np.ndarray):
    """A mesh ``{vertices, faces}`` turned by ``turn`` (a shift in roll steps, whole or not; the mirror)."""
    import trimesh

    rotation = turn_rotation(len(roll_rad), turn[0], turn[1])
    faces = np.asarray(mesh_arrays["faces"])
    return trimesh.Trimesh(np.asarray(mesh_arrays["vertices"], np.float64) @ rotation.T,
                           faces[:, ::-1] if turn[1] else faces, process=False)


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ckpt", type=Path, required=True, help="a Stage-1 checkpoint, or a Radar2Shape file holding one")
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--split", default="test")
    parser.add_argument("--classes", nargs="+", default=None, help="only these classes (default: every record)")
    parser.add_argument("--resolution", type=int, default=64, help="marching-cubes grid of the reconstruction")
    parser.add_argument("--seed", type=int, default=0, help="draws each record's true turn")
    parser.add_argument("--out", type=Path, required=True)
    return parser.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    import torch

    from data_modules.augment import turn_and_mirror
    from data_modules.datamodules import ShapeDataModule
    from radar2shape.atomic import write_text_atomic
    from radar2shape.errors import UserInputError
    from radar2shape.geometry.normalise import scaled
    from radar2shape.metrics.scoring import score_reconstruction
    from radar2shape.models.radar_diffusion import load_stage1
    from radar2shape.radar import simulate
    from radar2shape.reconstruction import Reconstruction

    try:
        stage1 = load_stage1(args.ckpt).eval()
        dm = ShapeDataModule(root=str(args.data))
        records = dm.records(args.split)
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    labels = dm.manifest["labels"][args.split]
    unknown = sorted(set(args.classes or []) - set(dm.class_names))
    if unknown:
        print(f"error: --classes: {unknown} not among {dm.class_names}", file=sys.stderr)
        return 2
    picked = [i for i, label in enumerate(labels) if args.classes is None or dm.class_names[label] in args.classes]
    torch.set_num_threads(2)
    rng = np.random.default_rng(args.seed)
    start = time.perf_counter()
    rows = []
    for i in picked:
        record = records[i]
        roll = np.asarray(record["roll_rad"])
        truth_turn = (int(rng.integers(len(roll))), bool(rng.integers(2)))
        observed = turn_and_mirror(record, *truth_turn)
        with torch.no_grad():
            mu, _ = stage1.encoder(torch.as_tensor(record["surface_points"][None, :2048], dtype=torch.float32))
            mesh = stage1.extract_mesh(mu, args.resolution)[0]
        if mesh is None or len(mesh.faces) == 0:  # nothing decoded: no response to search with
            print(f"{records.record_ids[i]}: the decoding is empty; left out", flush=True)
            continue
        canonical = {"vertices": np.asarray(mesh.vertices, np.float32), "faces": np.asarray(mesh.faces)}
        response = simulate(scaled(mesh, float(record["size_m"])), record["aspect_rad"], roll, record["freq_hz"])
        row = {"id": records.record_ids[i], "class": dm.class_names[labels[i]], "turn": truth_turn}

        def iou_at(turn):
            rec = Reconstruction(mesh=placed(canonical, turn, roll))
            return score_reconstruction(rec, observed["eval_points"], observed["occ_points"], observed["occ_inside"])["iou"]

        row["iou_true_turn"], row["iou_canonical"] = iou_at(truth_turn), iou_at((0, False))
        for name, band in (("full", False), ("band", True)):
            turn, scores = search(observed["radar"], response, roll, band)
            row[f"iou_{name}"] = iou_at(turn)
            row[f"exact_{name}"] = turn == truth_turn
            if not band:  # between steps, as RadarDiffusion.place_in_heading does by default
                row["iou_refined"] = iou_at((refined_shift(scores, turn, len(roll)), turn[1]))
            own, _ = search(observed["radar"], record["radar"], roll, band)
            row[f"own_iou_{name}"] = iou_at(own)  # the reconstruction placed where the true response points
            row[f"own_exact_{name}"] = own == truth_turn
        rows.append(row)
        print(f"{row['id']}: true turn {truth_turn}, IoU at it {row['iou_true_turn']:.3f}, estimated (full / band) "
              f"{row['iou_full']:.3f} / {row['iou_band']:.3f}, canonical {row['iou_canonical']:.3f}", flush=True)
    if not rows:
        print(f"error: --classes: no {args.split} record of {args.classes} in {args.data}", file=sys.stderr)
        return 2
    write_text_atomic(args.out, report(args, rows, time.perf_counter() - start))
    print(f"wrote {args.out}")
    return 0


def report(args, rows: list[dict], seconds: float) -> str:
    """Markdown: per-class and overall means; the share of exact turns; paired gaps to the oracle."""
    classes = sorted({r["class"] for r in rows})
    columns = (("iou_true_turn", "IoU at the true turn (oracle)"), ("iou_full", "IoU, turn from full dB map"),
               ("iou_refined", "IoU, full dB map, refined between steps"),
               ("iou_band", "IoU, turn from band-averaged map"), ("iou_canonical", "IoU, canonical heading kept"),
               ("own_iou_band", "IoU, turn from the true response (check)"))

    def mean(values):
        values = [v for v in values if not math.isnan(v)]
        return sum(values) / len(values) if values else math.nan

    lines = [f"# Heading from radar: `{args.ckpt}`", "",
             f"{len(rows)} {args.split} records of `{args.data}`, each turned by a random whole number of roll steps and "
             f"mirrored half the time (seed {args.seed}); the Stage-1 decoding of the record's surface points "
             f"({args.resolution}^3) simulated once with PO and its response re-indexed for all 2R turns; the turn "
             "whose dB map correlates best with the observed response places the reconstruction "
             f"(`scripts/heading_from_radar.py`, {seconds:.0f} s).", "",
             "| class (records) | " + " | ".join(title for _, title in columns) + " |", "|---" * (len(columns) + 1) + "|"]
    for name in [*classes, None]:
        subset = [r for r in rows if name is None or r["class"] == name]
        label = f"all ({len(subset)})" if name is None else f"{name} ({len(subset)})"
        lines.append(f"| {label} | " + " | ".join(f"{mean([r[key] for r in subset]):.3f}" for key, _ in columns) + " |")
    n = len(rows)
    lines += ["", "Exact turn found: " + ", ".join(
        f"{title} {sum(r[key] for r in rows)}/{n}" for key, title in (
            ("exact_full", "full dB map"), ("exact_band", "band-averaged map"),
            ("own_exact_full", "true response, full"), ("own_exact_band", "true response, band-averaged")))
        + " (a symmetric object has several right turns, so IoU is the measure)."]
    for key, title in (("iou_full", "full dB map"), ("iou_refined", "full dB map refined between steps"),
                       ("iou_band", "band-averaged map"), ("iou_canonical", "canonical heading")):
        diff = np.array([r[key] - r["iou_true_turn"] for r in rows])
        diff = diff[~np.isnan(diff)]
        se = diff.std(ddof=1) / math.sqrt(len(diff)) if len(diff) > 1 else math.nan
        lines.append(f"- {title} minus the oracle turn, paired: IoU {diff.mean():+.3f} ± {se:.3f}.")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
