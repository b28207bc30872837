"""``radar2shape evaluate PRED GT``: the shared metrics between two files, as the callback scores.

Evaluates in the files' own coordinates (the metrics' thresholds assume the normalised frame:
unit cube, longest side 1); ``--normalise`` first maps both by the ground truth's normalisation
(bbox centre at the origin, longest side 1). PRED may be a mesh (.obj/.off/.ply/.stl/.glb/.gltf),
a point cloud (.ply without faces, or .npy [N, 3]): a point set gets no IoU (null).
An empty or broken prediction scores the worst values; an unreadable file is an error.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import trimesh

from radar2shape.errors import UserInputError
from radar2shape.geometry.mesh_io import MESH_SUFFIXES, load_mesh
from radar2shape.geometry.normalise import normalisation
from radar2shape.geometry.query import contains, sample_surface
from radar2shape.metrics.functional import FSCORE_TAU, occupancy_points
from radar2shape.metrics.scoring import score_reconstruction
from radar2shape.models.base import Reconstruction


def configure_parser(parser: argparse.ArgumentParser) -> None:
    add = parser.add_argument
    add("pred", type=Path, help="predicted mesh or point cloud (.npy [N, 3] or faceless .ply)")
    add("gt", type=Path, help="ground-truth mesh")
    add("--points", type=int, default=30_000, help="surface samples per shape, Chamfer / F-score (default 30000)")
    add("--occ-points", type=int, default=100_000, help="uniform occupancy points for IoU (default 100000)")
    add("--tau", type=float, default=FSCORE_TAU, help="F-score threshold (default 0.01 = 1%% of the unit cube)")
    add("--seed", type=int, default=0, help="seed of all sampling (default 0)")
    add("--normalise", action="store_true", help="map both shapes by the ground truth's normalisation first")
    add("--json", action="store_true", help="print one line of JSON instead of a table")


def main(args: argparse.Namespace) -> int:
    for name in ("points", "occ_points", "tau"):
        if not getattr(args, name) > 0:
            raise UserInputError(f"--{name.replace('_', '-')} must be positive, got {getattr(args, name)}")
    scores = evaluate_files(args.pred, args.gt, args.points, args.occ_points, args.tau, args.seed, args.normalise)
    if args.json:
        print(json.dumps({k: (None if math.isnan(v) else v) for k, v in scores.items()}))
    else:
        print("\n".join(f"{k:<16} {'n/a' if math.isnan(v) else f'{v:.6g}'}" for k, v in scores.items()))
    return 0


def evaluate_files(
    pred_path: Path,
    gt_path: Path,
    n_points: int = 30_000,
    n_occ: int = 100_000,
    tau: float = FSCORE_TAU,
    seed: int = 0,
    normalise: bool = False,
) -> dict[str, float]:
    """Scores of the prediction file against the ground-truth file (see ``score_reconstruction``)."""
    gt = load_mesh(gt_path)
    pred = load_prediction(pred_path)
    if normalise:
        centre, scale = normalisation(gt.vertices)
        gt = _transformed(gt, centre, scale)
        pred = Reconstruction(
            mesh=None if pred.mesh is None else _transformed(pred.mesh, centre, scale),
            points=None if pred.points is None else (pred.points - centre) * scale,
        )
    # Seeds: prediction ``seed`` (as the callback: seed + record index 0), truth ``seed + 1``,
    # occupancy ``seed + 2``; distinct seeds give independent streams.
    gt_points, _ = sample_surface(gt, n_points, seed + 1)
    occ_points = occupancy_points(n_occ, seed + 2, [gt.bounds, _bounds(pred)])
    return score_reconstruction(pred, gt_points, occ_points, contains(gt, occ_points), n_points, tau, seed)


def load_prediction(path: Path) -> Reconstruction:
    """A prediction file as a Reconstruction; empty or faceless content is a (bad) prediction."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"{path}: no such file (expected a predicted mesh or point cloud)")
    if path.suffix.lower() == ".npy":
        try:
            points = np.load(path, allow_pickle=False)
        except Exception as err:
            raise UserInputError(f"{path}: cannot be read as a .npy array ({err})") from err
        if points.ndim != 2 or points.shape[1] != 3:
            raise UserInputError(f"{path}: expected a point array of shape [N, 3], got {list(points.shape)}")
        return Reconstruction(points=points.astype(np.float64))
    if path.suffix.lower() not in MESH_SUFFIXES:
        expected = ", ".join((".npy",) + MESH_SUFFIXES)
        raise UserInputError(f"{path}: unsupported suffix {path.suffix!r} (expected one of {expected})")
    try:
        loaded = trimesh.load(path, process=False)
    except Exception as err:  # trimesh raises many types for malformed files
        raise UserInputError(f"{path}: cannot be read ({type(err).__name__}: {err})") from err
    if isinstance(loaded, trimesh.PointCloud):
        return Reconstruction(points=np.asarray(loaded.vertices, dtype=np.float64))
    if isinstance(loaded, trimesh.Scene):
        loaded = loaded.to_mesh() if loaded.geometry else trimesh.Trimesh()
    if not isinstance(loaded, trimesh.Trimesh):
        raise UserInputError(f"{path}: holds neither a triangle mesh nor a point cloud ({type(loaded).__name__})")
    return Reconstruction(mesh=loaded)


def _transformed(mesh: trimesh.Trimesh, centre: np.ndarray, scale: float) -> trimesh.Trimesh:
    return trimesh.Trimesh((np.asarray(mesh.vertices) - centre) * scale, mesh.faces, process=False)


def _bounds(rec: Reconstruction) -> np.ndarray | None:
    if rec.mesh is not None:
        return rec.mesh.bounds if len(rec.mesh.vertices) else None
    return np.stack([rec.points.min(axis=0), rec.points.max(axis=0)]) if len(rec.points) else None
