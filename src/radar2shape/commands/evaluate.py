"""``radar2shape evaluate PRED GT``: the shared metrics between two files, as the callback scores.

Evaluates in the files' own coordinates (the metrics' thresholds assume the normalised frame:
unit cube, longest side 1); ``--normalise`` first maps both by the ground truth's normalisation
(bbox centre at the origin, longest side 1). PRED may be a mesh (.obj/.off/.ply/.stl/.glb/.gltf),
a point cloud (.ply without faces, or .npy [N, 3]): a point set gets no IoU (null).
An empty prediction (a mesh file with no geometry, an empty point array) scores the worst
values; a file that is not what its suffix says (text named .obj) is refused, as is any
unreadable file, and so are meshes whose face counts (read from the file headers before loading,
``preflight.BYTES_PER_FACE`` each) need more memory than the limit. A prediction whose size differs from the ground truth's by more than 10x gets
a one-line warning (the metrics assume one frame; see ``--normalise``). Lightning and torch are
never imported, so scoring a folder of meshes pays only numpy / trimesh start-up per file.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import sys
from typing import TYPE_CHECKING

import numpy as np

from radar2shape.errors import UserInputError
from radar2shape.preflight import add_memory_option, check_input_file, check_memory, count_faces, mesh_bytes

if TYPE_CHECKING:
    import trimesh

    from radar2shape.reconstruction import Reconstruction

# trimesh, scipy and igl (seconds on a small machine) are imported once the arguments are valid.

SCALE_WARN_RATIO = 10.0  # prediction vs ground-truth size beyond which the scores likely compare frames
# Peak bytes per sampled point: occupancy points + labels for two shapes; surface samples,
# distances and the k-d trees of two shapes (generous: an estimate for refusing, not a budget).
BYTES_PER_OCC_POINT, BYTES_PER_SURFACE_POINT = 64, 160


def configure_parser(parser: argparse.ArgumentParser) -> None:
    add = parser.add_argument
    add("pred", type=Path, help="predicted mesh or point cloud (.npy [N, 3] or faceless .ply)")
    add("gt", type=Path, help="ground-truth mesh")
    add("--points", type=int, default=30_000, help="surface samples per shape, Chamfer / F-score (default 30000)")
    add("--occ-points", type=int, default=100_000, help="uniform occupancy points for IoU (default 100000)")
    add("--tau", type=float, help="F-score threshold (default 0.01 = 1%% of the unit cube)")
    add("--seed", type=int, default=0, help="seed of all sampling (default 0)")
    frame = parser.add_mutually_exclusive_group()
    frame.add_argument("--normalise", action="store_true", help="map both shapes by the ground truth's normalisation first")
    frame.add_argument("--normalise-gt", action="store_true",
                       help="map only the ground truth into the normalised frame (centred, longest side 1), the frame "
                       "'reconstruct' writes in: score a reconstruction against the mesh it was simulated from")
    add("--up", default="z", choices=["x", "y", "z", "-x", "-y", "-z"],
        help="the ground truth's up axis, turned onto +z first (as 'simulate --up'; default z)")
    add("--json", action="store_true", help="print one line of JSON instead of a table")
    add_memory_option(parser)
    parser.epilog = ("Bad input is one 'error:' line (exit code 2). A prediction more than 10x larger or "
                     "smaller than the ground truth is scored with a one-line warning (try --normalise).")


def main(args: argparse.Namespace) -> int:
    if args.tau is None:
        from radar2shape.metrics.functional import FSCORE_TAU

        args.tau = FSCORE_TAU
    for name in ("points", "occ_points", "tau"):
        if not getattr(args, name) > 0:
            raise UserInputError(f"--{name.replace('_', '-')} must be positive, got {getattr(args, name)}")
    if args.seed < 0:
        raise UserInputError(f"--seed: expected a non-negative integer, got {args.seed}")
    points_bytes = args.occ_points * BYTES_PER_OCC_POINT + args.points * BYTES_PER_SURFACE_POINT
    check_memory(points_bytes, f"--points {args.points} with --occ-points {args.occ_points}", args.memory_limit_gb)
    check_input_file(args.pred, "pred", "a predicted mesh or point cloud")
    check_input_file(args.gt, "gt", "a ground-truth mesh")
    faces = {path: count_faces(path) or 0 for path in (args.pred, args.gt)}
    if any(faces.values()):  # from the headers, before either mesh is loaded
        check_memory(points_bytes + sum(mesh_bytes(n) for n in faces.values()),
                     " and ".join(f"{path} ({n} faces)" for path, n in faces.items()) + f" scored with --points "
                     f"{args.points} and --occ-points {args.occ_points}", args.memory_limit_gb)
    scores = evaluate_files(args.pred, args.gt, args.points, args.occ_points, args.tau, args.seed, args.normalise,
                            args.normalise_gt, args.up)
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
    tau: float | None = None,
    seed: int = 0,
    normalise: bool = False,
    normalise_gt: bool = False,
    up: str = "z",
) -> dict[str, float]:
    """Scores of the prediction file against the ground-truth file (see ``score_reconstruction``).

    ``tau`` defaults to the shared F-score threshold (``metrics.functional.FSCORE_TAU``). ``up``
    turns the ground truth into the body frame first; ``normalise`` maps both shapes by the ground
    truth's normalisation, ``normalise_gt`` only the ground truth (a reconstruction is already there).
    """
    from radar2shape.geometry.mesh_io import load_mesh
    from radar2shape.geometry.normalise import normalisation
    from radar2shape.geometry.query import contains, sample_surface
    from radar2shape.metrics.functional import FSCORE_TAU, occupancy_points
    from radar2shape.metrics.scoring import score_reconstruction
    from radar2shape.reconstruction import Reconstruction

    tau = FSCORE_TAU if tau is None else tau
    gt = load_mesh(gt_path)
    if up != "z":
        from radar2shape.geometry.frames import to_body_frame

        gt = to_body_frame(gt, up)
    if normalise_gt:
        gt = _transformed(gt, *normalisation(gt.vertices))
    pred = load_prediction(pred_path)
    warn_scale(pred, gt, pred_path, gt_path, normalise)
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


def size_ratio(pred: Reconstruction, gt: trimesh.Trimesh) -> float | None:
    """Longest bounding-box side of the prediction over the ground truth's (None if undefined)."""
    bounds = _bounds(pred)
    gt_side = float(np.ptp(gt.vertices, axis=0).max())
    if bounds is None or not np.isfinite(bounds).all() or not gt_side > 0:
        return None
    side = float((bounds[1] - bounds[0]).max())
    return side / gt_side if side > 0 else None


def warn_scale(pred: Reconstruction, gt: trimesh.Trimesh, pred_path: Path, gt_path: Path, normalise: bool) -> None:
    """One stderr line when the two shapes' sizes differ by more than ``SCALE_WARN_RATIO``."""
    ratio = size_ratio(pred, gt)
    if ratio is None or 1 / SCALE_WARN_RATIO <= ratio <= SCALE_WARN_RATIO:
        return
    hint = ("--normalise maps both by the ground truth only, so check the prediction's units"
            if normalise else "if they are in different frames, rerun with --normalise")
    print(f"warning: {pred_path} is {ratio:.3g} times the size of {gt_path} (longest bounding-box side); "
          f"the metrics compare them as they are: {hint}", file=sys.stderr)


def _has_content(path: Path) -> bool:
    """True when a text mesh file has any line besides blanks and comments."""
    with open(path, "rb") as handle:
        head = handle.read(1 << 20)
    return any(line.strip() and not line.lstrip().startswith(b"#") for line in head.splitlines())


def load_prediction(path: Path) -> Reconstruction:
    """A prediction file as a Reconstruction; empty or faceless content is a (bad) prediction."""
    import trimesh

    from radar2shape.geometry.mesh_io import MESH_SUFFIXES
    from radar2shape.reconstruction import Reconstruction

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
    if len(loaded.vertices) == 0 and _has_content(path):  # trimesh skips lines it does not know
        raise UserInputError(f"{path}: has content but no vertices or faces: not a {path.suffix} mesh "
                             "(an empty file is scored as an empty prediction)")
    return Reconstruction(mesh=loaded)


def _transformed(mesh: trimesh.Trimesh, centre: np.ndarray, scale: float) -> trimesh.Trimesh:
    import trimesh

    return trimesh.Trimesh((np.asarray(mesh.vertices) - centre) * scale, mesh.faces, process=False)


def _bounds(rec: Reconstruction) -> np.ndarray | None:
    if rec.mesh is not None:
        return rec.mesh.bounds if len(rec.mesh.vertices) else None
    return np.stack([rec.points.min(axis=0), rec.points.max(axis=0)]) if len(rec.points) else None
