"""Zero-shot monocone experiment (docs/measured.md): simulated "measurements" -> trained models -> scores.

The paper reconstructs a measured monoconic target with a model trained on simulated data. We
have no chamber, so each target is a blunted cone (``monocone`` family, options from
``--data-config``) measured in simulation the way a chamber would: physical optics at its
physical size (``--size-m``) over a fine aspect sweep at roll 0 (aspect-only) and a band that
electromagnetic scaling maps onto the models' 8-12 GHz, complex noise, then written in the
generic CSV format (``radar.measured``): "full" has every aspect, "partial" only one contiguous
window keeping ``--keep`` of them (the rows of the other aspects are absent). Each file goes
through the same path as ``radar2shape reconstruct --measured FILE --format csv --size-m S``
into every model of ``MODELS`` (full-observability runs for the full files, partial-observability
runs for the partial files, as in Table 1), and is scored against the normalised ground truth with
the project's metrics (Chamfer-L2 x10^3, IoU, F-score@1 %, and the roll-symmetric IoU-S / MATCH-S).

Writes ``--work-dir``/experiment/: ``scores.csv`` (per target, model and setting), ``experiment.json``
(the measurement settings and checkpoints) and ``surfaces.npz`` (figure points);
``radar2shape report --grid monocone`` turns them into reports/monocone/ (``make monocone`` runs both).

    .venv/bin/python scripts/monocone_experiment.py          # ~5 min on one CPU thread
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np
import torch
import yaml

from radar2shape.commands.reconstruct import load_model, measured_input, reconstruct_input
from radar2shape.errors import UserInputError
from radar2shape.geometry.families import make_family
from radar2shape.geometry.normalise import normalise, scaled
from radar2shape.geometry.query import contains, sample_surface
from radar2shape.metrics.functional import occupancy_points
from radar2shape.metrics.rollsym import predicted_profile, profile_match_distance, section_iou
from radar2shape.metrics.scoring import prediction_surface, score_reconstruction
from radar2shape.radar import add_noise, fixed_window_mask, simulate, to_db
from radar2shape.radar.measured import write_csv

ROOT = Path(__file__).resolve().parents[1]
# (row label, {setting: candidate checkpoints, first loadable wins}), paths relative to the repo. The
# 3D row prefers the medium Table-1 runs (seed 0), then the toy Table-1 runs, then this experiment's own Table-1-config runs (``make
# monocone-models``), then the demo's Stage 2 (trained with 0-70 % masks, so it serves both
# settings); the profile rows prefer the medium Table-2 runs (low noise, seed 0), then the tiny
# grid's; runs written by older code that no longer loads are skipped.
_TABLE1_MEDIUM = "runs/table1-medium/radar2shape-{}-seed0/fit/version_0/checkpoints/last.ckpt"
_TABLE1 = "runs/table1/radar2shape-{}/fit/version_0/checkpoints/last.ckpt"
_OWN = "runs/monocone/radar2shape-{}/fit/version_0/checkpoints/last.ckpt"
_ROLLSYM_MEDIUM = "runs/rollsym-medium/{}-{}-low-seed0/fit/version_0/checkpoints/last.ckpt"
_ROLLSYM = "runs/rollsym/{}-{}-medium/fit/version_0/checkpoints/epoch=59-step=720.ckpt"
_DEMO = "runs/demo/stage2/fit/version_0/checkpoints/last.ckpt"
MODELS = [  # (row of the monocone report layout, candidates); the row names the Table-1 cell folders too
    ("radar2shape", {s: [_TABLE1_MEDIUM.format(s), _TABLE1.format(s), _OWN.format(s), _DEMO] for s in ("full", "partial")}),
    ("unet", {s: [_ROLLSYM_MEDIUM.format("unet", s), _ROLLSYM.format("unet", s)] for s in ("full", "partial")}),
    ("invrt", {s: [_ROLLSYM_MEDIUM.format("invrt", s), _ROLLSYM.format("invrt", s)] for s in ("full", "partial")}),
]
SETTINGS = ("full", "partial")
TABLE1_METRICS = ("chamfer_l2_x1e3", "iou", "fscore_1pct")


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-config", type=Path, default=ROOT / "conf/data/monocone_tiny.yaml",
                        help="family options, seed and number of targets")
    parser.add_argument("--num", type=int, help="number of targets (default: the config's num)")
    parser.add_argument("--size-m", type=float, default=0.5, help="physical length of the measured cones (m)")
    parser.add_argument("--model-band-ghz", type=float, nargs=2, default=(7.5, 12.5),
                        help="measured band in model units (GHz at 1 m); the measurement runs at band / size")
    parser.add_argument("--num-freq", type=int, default=41)
    parser.add_argument("--aspect-step-deg", type=float, default=1.0)
    parser.add_argument("--noise-db", type=float, default=-60.0, help="noise power in dBsm at the model's 1 m scale")
    parser.add_argument("--keep", type=float, default=0.3, help="partial: fraction of aspects kept (one window)")
    parser.add_argument("--points", type=int, default=30_000, help="surface points per shape for CD / F-score")
    parser.add_argument("--occ", type=int, default=100_000, help="occupancy points for IoU")
    parser.add_argument("--work-dir", type=Path, default=ROOT / "runs/monocone")
    parser.add_argument("--table1-dir", type=Path, help="also write the rows as tested cells of a Table-1 sweep "
                        "folder (e.g. runs/table1), which `radar2shape report --grid table1` lists as extra rows")
    return parser.parse_args(argv)


def targets(config: dict, num: int | None):
    """(task, shape, normalised mesh, normalised profile) of every monocone target."""
    family = make_family(config["family"], config.get("family_options"))
    for task in family.plan(num or config["num"], {"test": 1.0}, config.get("seed", 0)):
        shape = family.generate(task)
        mesh, centre, scale = normalise(shape.mesh)
        profile = np.column_stack([shape.profile[:, 0] * scale, (shape.profile[:, 1] - centre[2]) * scale])
        yield task, shape, mesh, profile


def measure(mesh, index: int, args, folder: Path) -> dict[str, Path]:
    """Full and partial CSV "measurements" of a normalised mesh at ``args.size_m`` metres."""
    aspect_deg = np.arange(0.0, 180.0 + 1e-9, args.aspect_step_deg)
    freq_ghz = np.linspace(*args.model_band_ghz, args.num_freq) / args.size_m
    response = simulate(scaled(mesh, args.size_m), np.radians(aspect_deg), [0.0], freq_ghz * 1e9)[:, 0]
    level = args.noise_db + 20 * np.log10(args.size_m)  # -60 dB at 1 m is -66 dB at 0.5 m
    db = to_db(add_noise(response, level, np.random.default_rng(index)), -200.0)
    keep = fixed_window_mask(len(aspect_deg), 1, args.keep, seed=index)[:, 0]
    out = {}
    for setting, rows in (("full", np.ones_like(keep)), ("partial", keep)):
        a, f = np.meshgrid(aspect_deg[rows], freq_ghz, indexing="ij")
        out[setting] = write_csv(folder / f"monocone_{index:03d}_{setting}.csv", a.ravel(), f.ravel(), db[rows].ravel())
    return out


def score(recon, gt: dict) -> dict[str, float]:
    """Table-1 metrics plus IoU-S / MATCH-S (an invalid predicted profile scores IoU-S 0, MATCH-S skipped)."""
    scores = score_reconstruction(recon, gt["points"], gt["occ"], gt["inside"], len(gt["points"]))
    profile = predicted_profile(recon)
    valid = profile is not None
    scores["iou_s"] = section_iou(profile, gt["profile"]) if valid else 0.0
    scores["match_s"] = profile_match_distance(profile, gt["profile"]) if valid else float("nan")
    return scores


def mean_std(values: list[float]) -> tuple[float, float, int]:
    v = np.asarray([x for x in values if np.isfinite(x)], float)
    return (float(v.mean()), float(v.std()), len(v)) if len(v) else (float("nan"), float("nan"), 0)


def load_models() -> tuple[dict, list[tuple[str, str, str]]]:
    """{(label, setting): (model, radar spec)} and (label, full ckpt, partial ckpt) of the rows that load."""
    loaded, used = {}, []
    for label, candidates in MODELS:
        chosen = {}
        for setting in SETTINGS:
            for ckpt in candidates[setting]:
                if not (ROOT / ckpt).is_file():
                    continue
                try:
                    model = load_model(ROOT / ckpt)
                    loaded[label, setting] = (model, model.radar_spec)
                except UserInputError as err:
                    print(f"skipping {ckpt}: {err}")
                    continue
                chosen[setting] = ckpt
                break
        if len(chosen) == len(SETTINGS):
            used.append((label, chosen["full"], chosen["partial"]))
        else:
            print(f"skipping {label}: no loadable checkpoint among {candidates}")
            for setting in SETTINGS:
                loaded.pop((label, setting), None)
    if not used:
        raise SystemExit("no checkpoint found: run make demo and make sweep GRID=rollsym first")
    return loaded, used


FIGURE_TARGETS = 4
CONTROL = "_control"  # rows of a model fed another target's radar


def write_table1_cells(rows: list[dict], models: list[tuple], folder: Path) -> None:
    """``FOLDER/monocone_<model>-<setting>/test/version_0/metrics.csv`` in the Lightning CSV-logger layout.

    The Table-1 report reads any ``<model>-<group>`` folder with a logged test as a cell, so these
    become the "monocone_*" rows of `radar2shape report --grid table1` (columns full / partial).
    """
    for name, *_ in models:
        for setting in SETTINGS:
            picked = [r for r in rows if r["model"] == name and r["setting"] == setting]
            values = {"epoch": 0, "step": 0}
            for key in TABLE1_METRICS:
                mean, std, _ = mean_std([r[key] for r in picked])
                values[f"test/{key}_mean"], values[f"test/{key}_std"] = mean, std
            path = folder / f"monocone_{name}-{setting}" / "test" / "version_0" / "metrics.csv"
            path.parent.mkdir(parents=True, exist_ok=True)
            with open(path, "w", newline="") as handle:
                writer = csv.DictWriter(handle, fieldnames=list(values))
                writer.writeheader()
                writer.writerow(values)



def write_scores(rows: list[dict], pictures: dict, cases: list, models: list[tuple], args, seconds: float) -> Path:
    """``scores.csv``, ``experiment.json`` and ``surfaces.npz`` under ``WORK_DIR/experiment`` (the
    inputs of the ``monocone`` report layout)."""
    folder = args.work_dir / "experiment"
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "scores.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    config = args.data_config.relative_to(ROOT) if args.data_config.is_relative_to(ROOT) else args.data_config
    info = {"targets": len(cases), "data_config": str(config), "size_m": args.size_m,
            "model_band_ghz": list(args.model_band_ghz), "num_freq": args.num_freq,
            "aspect_step_deg": args.aspect_step_deg, "noise_db": args.noise_db, "keep": args.keep,
            "seconds": round(seconds, 1), "checkpoints": {name: {"full": full, "partial": partial} for name, full, partial in models}}
    (folder / "experiment.json").write_text(json.dumps(info, indent=2))
    surfaces = {f"gt/{i}": gt["points"][:8192] for i, (_, _, gt) in enumerate(cases[:FIGURE_TARGETS])}
    surfaces.update({f"{setting}/{name}/{i}": points for setting, by_model in pictures.items()
                     for name, clouds in by_model.items() for i, points in enumerate(clouds)})
    np.savez_compressed(folder / "surfaces.npz", **surfaces)
    print(f"wrote {folder}; radar2shape report --grid monocone writes the tables")
    return folder


def main(argv=None) -> int:
    args = parse_args(argv)
    torch.set_num_threads(1)
    start = time.perf_counter()
    config = yaml.safe_load(args.data_config.read_text())
    loaded, models = load_models()
    cases = []  # (task, files, ground truth) per target
    for index, (task, _, mesh, profile) in enumerate(targets(config, args.num)):
        occ = occupancy_points(args.occ, index)
        cases.append((task, measure(mesh, index, args, args.work_dir / "measurements"),
                      {"points": sample_surface(mesh, args.points, index)[0], "occ": occ,
                       "inside": contains(mesh, occ), "profile": profile}))
    rows, pictures = [], {setting: {} for setting in SETTINGS}
    for (label, setting), (model, spec) in loaded.items():
        recons = []
        for index, (task, files, gt) in enumerate(cases):
            grid = measured_input([files[setting]], "csv", spec, roll_symmetric=True, size_m=args.size_m)
            recons.append(reconstruct_input(model, grid, seed=index)[0])
            rows.append({"target": index, "seed": task.seed, "model": label, "setting": setting,
                         "observed_cells": int(grid.mask.sum()), **score(recons[-1], gt)})
        # Control: target i scored against the reconstruction from target i+1's radar. If the
        # radar carried no information this would score as well as the real rows.
        for index, (task, _, gt) in enumerate(cases):
            rows.append({"target": index, "seed": task.seed, "model": label + CONTROL, "setting": setting,
                         "observed_cells": -1, **score(recons[(index + 1) % len(cases)], gt)})
        pictures[setting][label] = [prediction_surface(rec, 8192, 0) for rec in recons[:FIGURE_TARGETS]]
        real = [r["iou"] for r in rows if r["model"] == label and r["setting"] == setting]
        print(f"{label} / {setting}: IoU {np.mean(real):.3f}", flush=True)
    write_scores(rows, pictures, cases, models, args, time.perf_counter() - start)
    if args.table1_dir is not None:
        write_table1_cells(rows, models, args.table1_dir)
        print(f"wrote the monocone_* cells into {args.table1_dir}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
