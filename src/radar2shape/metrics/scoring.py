"""A model's :class:`Reconstruction` -> per-sample scores, shared by the callback and the CLI.

Rules (docs/metrics.md):
- a mesh prediction is sampled area-uniformly (``n_points``) for Chamfer / F-score and its
  containment of the occupancy points gives IoU;
- a point-set prediction (``mesh is None``) is subsampled to ``n_points`` for Chamfer / F-score;
  it has no volume, so its IoU is undefined: ``nan``, which the metric classes skip (counted
  apart), rather than a made-up value from a thickened point cloud;
- a degenerate prediction (no reconstruction, no faces or points, zero area, any NaN/inf)
  scores the worst values: Chamfer ``CHAMFER_WORST``, F-score 0, and IoU 0 unless it is a
  non-empty point set (never any IoU, so a point-set model's IoU stays undefined throughout).
"""

from __future__ import annotations

import math

import numpy as np
import trimesh

from radar2shape.geometry.query import contains, sample_surface
from radar2shape.metrics.functional import (
    CHAMFER_SCALE,
    FSCORE_TAU,
    chamfer_from_distances,
    fscore_from_distances,
    iou,
    metric_names,
    surface_distances,
)
from radar2shape.reconstruction import Reconstruction


def _usable_mesh(mesh: trimesh.Trimesh) -> bool:
    return len(mesh.faces) > 0 and bool(np.isfinite(mesh.vertices).all())


def prediction_surface(rec: Reconstruction | None, n_points: int, seed: int | None = 0) -> np.ndarray:
    """Surface samples ``[<= n_points, 3]`` of a prediction; empty ``[0, 3]`` when degenerate."""
    if rec is not None and rec.mesh is not None:
        return sample_surface(rec.mesh, n_points, seed)[0] if _usable_mesh(rec.mesh) else np.zeros((0, 3))
    points = np.zeros((0, 3)) if rec is None or rec.points is None else np.asarray(rec.points).reshape(-1, 3)
    if len(points) > n_points:
        points = points[np.random.default_rng(seed).choice(len(points), n_points, replace=False)]
    return points


def prediction_inside(rec: Reconstruction | None, occ_points: np.ndarray) -> np.ndarray | None:
    """Containment of ``occ_points`` in the prediction; ``None`` for a point set (IoU undefined)."""
    if rec is not None and rec.mesh is None and rec.points is not None and len(rec.points) > 0:
        return None
    if rec is None or rec.mesh is None or not _usable_mesh(rec.mesh):
        return np.zeros(len(occ_points), dtype=bool)
    return contains(rec.mesh, occ_points)


def score_reconstruction(
    rec: Reconstruction | None,
    gt_points: np.ndarray,
    occ_points: np.ndarray,
    gt_inside: np.ndarray,
    n_points: int = 30_000,
    tau: float = FSCORE_TAU,
    seed: int | None = 0,
) -> dict[str, float]:
    """``{chamfer_l2_x1e3, iou, fscore_<tau>pct}`` of one prediction against one ground truth.

    ``gt_points`` are ground-truth surface samples, ``occ_points`` / ``gt_inside`` the occupancy
    points with their ground-truth labels (as in the batch keys ``eval_points``, ``occ_points``,
    ``occ_inside``). Values are in reported units (Chamfer x 10^3); IoU is ``nan`` when undefined.
    """
    names = metric_names(tau)
    distances = surface_distances(prediction_surface(rec, n_points, seed), gt_points)
    inside = prediction_inside(rec, occ_points)
    return {
        names["chamfer"]: CHAMFER_SCALE * chamfer_from_distances(distances),
        names["iou"]: math.nan if inside is None else iou(inside, gt_inside),
        names["fscore"]: fscore_from_distances(distances, tau),
    }
