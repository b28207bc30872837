"""Per-sample shape metrics (docs/design.md section 6): the one definition every model is scored by.

Coordinates are the normalised frame (unit cube [-0.5, 0.5]^3, longest side 1). Degenerate
inputs (no points, non-finite values) score the worst value instead of raising, so a broken
prediction lowers a model's score and never stops an evaluation.
"""

from __future__ import annotations

import numpy as np

from radar2shape.geometry.query import nearest_distance

PADDING = 0.05  # the IoU sampling cube is [-0.5 - PADDING, 0.5 + PADDING]^3 (as the data builders)
CHAMFER_SCALE = 1e3  # Chamfer-L2 is reported x 10^3
# Worst Chamfer-L2 (unscaled): each of its two terms is at most the squared diagonal of the
# padded cube, 3 * 1.1^2, for any two point sets inside it; so 2 * 3.63 = 7.26 (7260 x 10^3).
CHAMFER_WORST = 2.0 * 3.0 * (1.0 + 2.0 * PADDING) ** 2
FSCORE_TAU = 0.01  # 1 % of the unit cube's side


def metric_names(tau: float = FSCORE_TAU) -> dict[str, str]:
    """Logged / printed names: ``chamfer_l2_x1e3``, ``iou``, ``fscore_1pct`` (for tau = 0.01)."""
    return {"chamfer": "chamfer_l2_x1e3", "iou": "iou", "fscore": f"fscore_{100 * tau:g}pct"}


def _valid(points: np.ndarray) -> bool:
    return len(points) > 0 and bool(np.isfinite(points).all())


def surface_distances(pred: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Nearest-neighbour distances pred -> gt and gt -> pred; ``None`` if either set is degenerate."""
    pred, gt = np.asarray(pred).reshape(-1, 3), np.asarray(gt).reshape(-1, 3)
    if not (_valid(pred) and _valid(gt)):
        return None
    return nearest_distance(pred, gt), nearest_distance(gt, pred)


def chamfer_from_distances(distances: tuple[np.ndarray, np.ndarray] | None) -> float:
    """Mean squared distance pred -> gt plus gt -> pred (unscaled); worst if degenerate."""
    if distances is None:
        return CHAMFER_WORST
    to_gt, to_pred = distances
    return float(np.mean(to_gt**2) + np.mean(to_pred**2))


def fscore_from_distances(distances: tuple[np.ndarray, np.ndarray] | None, tau: float = FSCORE_TAU) -> float:
    """F = 2PR / (P + R); P: share of predicted points within ``tau`` of the truth, R: vice versa."""
    if distances is None:
        return 0.0
    precision, recall = float(np.mean(distances[0] < tau)), float(np.mean(distances[1] < tau))
    return 0.0 if precision + recall == 0 else 2.0 * precision * recall / (precision + recall)


def chamfer_l2(pred: np.ndarray, gt: np.ndarray) -> float:
    """Chamfer-L2 between two surface samples (unscaled; multiply by CHAMFER_SCALE to report)."""
    return chamfer_from_distances(surface_distances(pred, gt))


def fscore(pred: np.ndarray, gt: np.ndarray, tau: float = FSCORE_TAU) -> float:
    """F-score at threshold ``tau`` between two surface samples."""
    return fscore_from_distances(surface_distances(pred, gt), tau)


def iou(pred_inside: np.ndarray, gt_inside: np.ndarray) -> float:
    """|pred & gt| / |pred | gt| over the same occupancy points; 1 when both are empty."""
    pred_inside, gt_inside = np.asarray(pred_inside, bool), np.asarray(gt_inside, bool)
    union = np.count_nonzero(pred_inside | gt_inside)
    return 1.0 if union == 0 else np.count_nonzero(pred_inside & gt_inside) / union


def occupancy_points(n: int, seed: int | np.random.Generator | None = None, cover: list | None = None) -> np.ndarray:
    """``n`` IoU points uniform in the padded unit cube, grown to hold every box in ``cover``.

    ``cover``: bounding boxes ``[[lo], [hi]]`` (None entries ignored). The IoU estimate is
    unbiased in any box that holds both shapes; the padded unit cube is the datasets' box, so
    normalised shapes are scored exactly as in training runs.
    """
    lo, hi = np.full(3, -0.5 - PADDING), np.full(3, 0.5 + PADDING)
    for box in cover or []:
        if box is not None and np.isfinite(box).all():
            lo, hi = np.minimum(lo, box[0]), np.maximum(hi, box[1])
    return np.random.default_rng(seed).uniform(lo, hi, size=(n, 3)).astype(np.float32)
