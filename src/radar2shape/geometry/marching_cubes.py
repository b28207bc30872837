"""SDF grid -> triangle mesh: the last step of every implicit model's reconstruction.

Grid convention: ``sdf[i, j, k]`` is the SDF at ``(x_i, y_j, z_k)`` with
``x_i = lo + i * (hi - lo) / (R - 1)`` (``np.meshgrid(..., indexing="ij")``; the grid includes
both bounds), negative inside. Meshes come out in the same coordinates, normals outward.
"""

from __future__ import annotations

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


@torch.no_grad()
def extract_mesh(
    sdf_fn: Callable[[torch.Tensor], torch.Tensor],
    resolution: int = 64,
    bounds: tuple[float, float] = (-0.5, 0.5),
    batch_points: int = 65536,
    device: torch.device | str | None = None,
) -> trimesh.Trimesh:
    """Evaluate ``sdf_fn`` (``[M, 3] -> [M]`` or ``[M, 1]``) on the grid in chunks, then mesh it.

    Chunking bounds memory for any resolution; ``device`` is where the query points are put
    (the model's device), results come back to the CPU per chunk.
    """
    points = torch.from_numpy(grid_points(resolution, bounds))
    values = [
        sdf_fn(chunk.to(device)).reshape(-1).float().cpu() for chunk in torch.split(points, batch_points)
    ]
    sdf = torch.cat(values).reshape(resolution, resolution, resolution).numpy()
    return sdf_grid_to_mesh(sdf, bounds)
