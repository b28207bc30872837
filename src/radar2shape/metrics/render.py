"""Quick-look pictures of reconstructions next to the ground truth (PNG, no display needed).

Orthographic depth splats of surface samples: works the same for meshes (sampled) and point
sets, costs milliseconds, and needs only numpy and matplotlib's object API (no display, no
pyplot state).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

# Views as (azimuth, elevation) in degrees: front three-quarter and top-down.
VIEWS = ((-55.0, 25.0), (0.0, 90.0))


def depth_image(points: np.ndarray, azimuth: float, elevation: float, size: int = 160, extent: float = 0.6) -> np.ndarray:
    """Nearest depth per pixel (larger = closer) of points seen orthographically; NaN = empty.

    The view looks at the origin from direction (azimuth, elevation); ``extent`` is the half
    width of the square window (the padded unit cube fits).
    """
    image = np.full((size, size), np.nan)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    if len(points) == 0:
        return image
    a, e = np.radians(azimuth), np.radians(elevation)
    toward = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])  # toward the viewer
    right = np.cross([0.0, 0.0, 1.0], toward) if abs(toward[2]) < 0.999 else np.array([0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(toward, right)
    u, v, depth = points @ right, points @ up, points @ toward
    col = np.floor((u + extent) / (2 * extent) * size).astype(int)
    row = np.floor((extent - v) / (2 * extent) * size).astype(int)
    flat = np.full(size * size, -np.inf)
    for dr, dc in ((0, 0), (0, 1), (1, 0), (1, 1)):  # 2x2 splats: no see-through gaps between samples
        r, c = row + dr, col + dc
        ok = (c >= 0) & (c < size) & (r >= 0) & (r < size)
        np.maximum.at(flat, r[ok] * size + c[ok], depth[ok])  # the largest depth is the closest
    image.ravel()[np.isfinite(flat)] = flat[np.isfinite(flat)]
    return image


def save_comparison(path: str | Path, pred_points: np.ndarray, gt_points: np.ndarray, title: str = "") -> Path:
    """PNG with the prediction (top row) above the ground truth (bottom row) in each view."""
    from matplotlib.figure import Figure  # object API: no pyplot, no global backend switch

    from radar2shape.atomic import atomic_path

    path = Path(path)
    fig = Figure(figsize=(2.6 * len(VIEWS), 5.4))
    axes = fig.subplots(2, len(VIEWS), squeeze=False)
    for row, (label, points) in enumerate((("prediction", pred_points), ("ground truth", gt_points))):
        for col, (azimuth, elevation) in enumerate(VIEWS):
            ax = axes[row, col]
            ax.imshow(depth_image(points, azimuth, elevation), cmap="viridis", vmin=-0.6, vmax=0.6)
            ax.set_xticks([])
            ax.set_yticks([])
            if col == 0:
                ax.set_ylabel(label)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as temp:
        fig.savefig(temp, dpi=100)
    return path
