"""SDF grid -> triangle mesh: the last step of every implicit model's reconstruction.

Grid convention: ``sdf[i, j, k]`` is the SDF at ``(x_i, y_j, z_k)`` with
``x_i = lo + i * (hi - lo) / (R - 1)`` (``np.meshgrid(..., indexing="ij")``; the grid includes
both bounds), negative inside. Meshes come out in the same coordinates, normals outward.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import torch
import trimesh
from skimage.measure import marching_cubes


def grid_points(resolution: int, bounds: tuple[float, float] = (-0.5, 0.5)) -> np.ndarray:
    """The ``[R^3, 3]`` float32 grid points in the order ``sdf.reshape(R, R, R)`` expects."""
    axis = np.linspace(bounds[0], bounds[1], resolution, dtype=np.float32)
    return np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)


def sdf_grid_to_mesh(sdf: np.ndarray, bounds: tuple[float, float] = (-0.5, 0.5)) -> trimesh.Trimesh:
    """Zero level set of a cubic SDF grid as a closed mesh with outward normals.

    The grid is padded with one layer of large "outside" values, so a surface cut by the grid
    boundary (normalised shapes touch the unit cube) is capped at the boundary instead of left
    open: the mesh is always closed, which containment and IoU need. NaN values count as outside (a
    partly broken prediction still yields its valid part). Returns an empty ``Trimesh`` when
    there is no zero crossing, so callers score it as an empty prediction rather than crash.
    """
    sdf = np.asarray(sdf, dtype=np.float32)
    if sdf.ndim != 3 or len(set(sdf.shape)) != 1 or sdf.shape[0] < 2:
        raise ValueError(f"sdf must be a cubic grid [R, R, R] with R >= 2, got shape {sdf.shape}")
    finite = np.isfinite(sdf)
    if not finite.any():
        return trimesh.Trimesh()
    spacing = (bounds[1] - bounds[0]) / (sdf.shape[0] - 1)
    # Large enough that the interpolated crossing (the cap) lies within 1e-3 cell of the boundary.
    outside = 1e3 * max(float(np.abs(sdf[finite]).max()), spacing)
    sdf = np.pad(np.where(finite, sdf, outside), 1, constant_values=outside)
    if sdf.min() >= 0.0:
        return trimesh.Trimesh()
    # skimage's default "descent" winding gives outward normals for a negative-inside SDF
    # (checked by the sign of the volume in tests/metrics/test_marching_cubes.py).
    vertices, faces, _, _ = marching_cubes(sdf, level=0.0, spacing=(spacing,) * 3, gradient_direction="descent")
    return trimesh.Trimesh(vertices + (bounds[0] - spacing), faces, process=False)


# Coarsest block size (cells) of the narrow-band evaluation, and how far (in block diagonals) a
# block's corners may sit from the surface before the block is refined. 1 suffices for an exact
# distance function (1-Lipschitz); learned SDFs are only close to one, hence the slack.
COARSEST_BLOCK = 8
BAND_SLACK = 1.5


def _axis_levels(resolution: int, block: int) -> list[np.ndarray]:
    """Grid indices per refinement level along one axis: every ``s``-th index plus the last,
    for s = block, block / 2, ..., 1."""
    levels = []
    while block >= 1:
        levels.append(np.union1d(np.arange(0, resolution, block), [resolution - 1]))
        block //= 2
    return levels


def _parents(fine: np.ndarray, coarse: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each fine index, the two coarse blocks (index pairs) that hold it (equal inside a block)."""
    n_blocks = len(coarse) - 1
    upper = np.minimum(np.searchsorted(coarse, fine, side="right") - 1, n_blocks - 1)
    lower = np.maximum(np.searchsorted(coarse, fine, side="left") - 1, 0)
    return np.minimum(lower, upper), upper


def _narrow_band_grid(evaluate: Callable[[np.ndarray], np.ndarray], resolution: int, spacing: float,
                      distance_limit: float | None = None) -> np.ndarray:
    """The SDF on the full grid, evaluated exactly only near the surface.

    Blocks of ``COARSEST_BLOCK`` cells are halved while one of their corners lies within
    BAND_SLACK block diagonals of the surface (or the corners disagree in sign, or one is NaN);
    a block that stops early holds no surface (its corners are farther from the surface than any
    of its points), so its points get its corners' sign at the block's margin: the same signs, and
    so the same marching-cubes mesh, as evaluating every point, for a fraction of the queries.
    An SDF learned with a truncated loss is a distance only up to the truncation
    (``distance_limit``): blocks whose margin exceeds it are always refined.
    """
    sdf = np.full((resolution,) * 3, np.nan, dtype=np.float32)
    exact = np.zeros(sdf.shape, dtype=bool)
    levels = _axis_levels(resolution, COARSEST_BLOCK)
    need = np.ones((len(levels[0]),) * 3, dtype=bool)  # points of the current level to evaluate
    for depth, index in enumerate(levels):
        grid = np.ix_(index, index, index)
        todo = np.nonzero(need & ~exact[grid])
        if len(todo[0]):
            target = tuple(index[t] for t in todo)
            sdf[target] = evaluate(np.stack(target, axis=1))
            exact[target] = True
        if depth + 1 == len(levels):
            break
        stacked = np.stack(_corners(sdf[grid]))  # [8, n-1, n-1, n-1]; refined blocks' corners are known
        margin = BAND_SLACK * (COARSEST_BLOCK >> depth) * math.sqrt(3.0) * spacing
        with np.errstate(invalid="ignore"):
            refine = (np.nan_to_num(np.abs(stacked), nan=0.0).min(axis=0) < margin)
            refine |= (stacked > 0).any(axis=0) & (stacked <= 0).any(axis=0)
        if distance_limit is not None and margin > distance_limit:
            refine[...] = True
        # Blocks that stop here: their still-unknown points get the corners' sign at the margin.
        settled = ~np.isnan(stacked).any(axis=0) & ~refine
        _fill_settled(sdf, exact, index, settled, np.sign(stacked[0]) * margin)
        lo, hi = _parents(levels[depth + 1], index)  # the same along every axis
        need = np.logical_or.reduce([refine[np.ix_(a, b, c)] for a in (lo, hi) for b in (lo, hi) for c in (lo, hi)])
    return sdf


def _corners(values: np.ndarray) -> list[np.ndarray]:
    """The eight corner views [n-1, n-1, n-1] of the blocks of a level's point array [n, n, n]."""
    n = values.shape[0] - 1
    return [values[a:n + a, b:n + b, c:n + c] for a in (0, 1) for b in (0, 1) for c in (0, 1)]


def _fill_settled(sdf: np.ndarray, exact: np.ndarray, index: np.ndarray, settled: np.ndarray,
                  value: np.ndarray) -> None:
    """Give every still-unknown (NaN) point of each settled block that block's constant value.

    A point on a face between blocks is filled from the lower one when that one is settled; when it
    is refined instead, the point is evaluated at a finer level."""
    parent = np.minimum(np.searchsorted(index, np.arange(sdf.shape[0]), side="right") - 1, len(index) - 2)
    where = np.ix_(parent, parent, parent)
    fill = np.isnan(sdf) & ~exact & settled[where]
    sdf[fill] = value[where][fill]


@torch.no_grad()
def extract_mesh(
    sdf_fn: Callable[[torch.Tensor], torch.Tensor],
    resolution: int = 64,
    bounds: tuple[float, float] = (-0.5, 0.5),
    batch_points: int = 65536,
    device: torch.device | str | None = None,
    narrow_band: bool = True,
    distance_limit: float | None = None,
) -> trimesh.Trimesh:
    """Evaluate ``sdf_fn`` (``[M, 3] -> [M]`` or ``[M, 1]``) on the grid in chunks, then mesh it.

    With ``narrow_band`` (default) only the points near the surface are evaluated
    (:func:`_narrow_band_grid`); the mesh is the one every point would give. ``distance_limit``:
    the magnitude up to which ``sdf_fn`` is a distance (a model's loss truncation; None: everywhere). Chunking bounds memory
    for any resolution; ``device`` is where the query points are put (the model's device), results
    come back to the CPU per chunk.
    """
    axis = np.linspace(bounds[0], bounds[1], resolution, dtype=np.float32)

    def evaluate(index: np.ndarray) -> np.ndarray:
        points = torch.from_numpy(axis[index])
        values = [sdf_fn(chunk.to(device)).reshape(-1).float().cpu() for chunk in torch.split(points, batch_points)]
        return torch.cat(values).numpy()

    if narrow_band and resolution > COARSEST_BLOCK:
        spacing = (bounds[1] - bounds[0]) / (resolution - 1)
        sdf = _narrow_band_grid(evaluate, resolution, spacing, distance_limit)
    else:
        full = np.stack(np.meshgrid(*(np.arange(resolution),) * 3, indexing="ij"), axis=-1).reshape(-1, 3)
        sdf = evaluate(full).reshape(resolution, resolution, resolution)
    return sdf_grid_to_mesh(sdf, bounds)
