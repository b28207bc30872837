"""Axis-aligned feature planes (xy, xz, yz): project point features onto them and read them back.

One convention for both directions (ConvONet's): a plane of resolution ``R`` tiles
``[-bound, bound]^2`` into ``R x R`` cells; cell ``(row, col)`` holds the points whose first plane
axis falls in column ``col`` and second in row ``row``; reading uses ``F.grid_sample`` with
``align_corners=False`` so pixel centres sit at cell centres.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

PLANE_AXES = ((0, 1), (0, 2), (1, 2))  # xy, xz, yz
PLANE_NAMES = ("xy", "xz", "yz")


def plane_uv(points: torch.Tensor, bound: float) -> torch.Tensor:
    """Coordinates of ``points [B, N, 3]`` on the three planes, in ``[-1, 1]``: ``[B, 3, N, 2]``."""
    uv = torch.stack([points[..., list(axes)] for axes in PLANE_AXES], dim=1)
    return (uv / bound).clamp(-1.0, 1.0)


def plane_cell_index(points: torch.Tensor, resolution: int, bound: float) -> torch.Tensor:
    """Flat cell index ``row * R + col`` of each point on each plane: long ``[B, 3, N]``."""
    cell = ((plane_uv(points, bound) + 1) * 0.5 * resolution).long().clamp(0, resolution - 1)
    return cell[..., 1] * resolution + cell[..., 0]


def scatter_mean(features: torch.Tensor, index: torch.Tensor, n_cells: int) -> torch.Tensor:
    """Mean of ``features [B, N, C]`` over points sharing a cell ``index [B, N]``: ``[B, C, n_cells]``.

    Empty cells are zero, so an empty region of a plane reads as "no surface here".
    """
    b, _, c = features.shape
    sums = features.new_zeros(b, c, n_cells).scatter_add_(2, index[:, None, :].expand(-1, c, -1), features.transpose(1, 2))
    counts = features.new_zeros(b, 1, n_cells).scatter_add_(2, index[:, None, :], features.new_ones(b, 1, index.shape[1]))
    return sums / counts.clamp(min=1.0)


def project_to_planes(features: torch.Tensor, index: torch.Tensor, resolution: int) -> torch.Tensor:
    """Mean-pool point features ``[B, N, C]`` onto the planes given ``index [B, 3, N]``: ``[B, 3, C, R, R]``."""
    b, _, c = features.shape
    planes = [scatter_mean(features, index[:, p], resolution * resolution) for p in range(3)]
    return torch.stack(planes, dim=1).reshape(b, 3, c, resolution, resolution)


def local_pool(features: torch.Tensor, index: torch.Tensor, resolution: int) -> torch.Tensor:
    """Each point gets the mean feature of its cell, summed over the three planes: ``[B, N, C]``.

    ConvONet's local pooling (scatter-then-gather), which lets a per-point network see its
    neighbourhood at the level's resolution without any nearest-neighbour search.
    """
    c = features.shape[-1]
    pooled = features.new_zeros(features.shape)
    for p in range(3):
        cells = scatter_mean(features, index[:, p], resolution * resolution)  # [B, C, R*R]
        pooled = pooled + cells.gather(2, index[:, p, None, :].expand(-1, c, -1)).transpose(1, 2)
    return pooled


def sample_planes(planes: torch.Tensor, points: torch.Tensor, bound: float) -> torch.Tensor:
    """Bilinear read of ``planes [B, 3, C, R, R]`` at ``points [B, Q, 3]``, summed over planes: ``[B, Q, C]``."""
    b, _, c, r, _ = planes.shape
    grid = plane_uv(points, bound).reshape(b * 3, 1, -1, 2)
    sampled = F.grid_sample(
        planes.reshape(b * 3, c, r, r), grid, mode="bilinear", padding_mode="border", align_corners=False
    )  # [B*3, C, 1, Q]
    return sampled.reshape(b, 3, c, -1).sum(1).transpose(1, 2)
