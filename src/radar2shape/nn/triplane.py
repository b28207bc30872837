"""Axis-aligned feature planes (xy, xz, yz): project point features onto them and read them back.

One convention for both directions (ConvONet's): a plane of resolution ``R`` tiles
``[-bound, bound]^2`` into ``R x R`` cells; cell ``(row, col)`` holds the points whose first plane
axis falls in column ``col`` and second in row ``row``; reading uses ``F.grid_sample`` with
``align_corners=False`` so pixel centres sit at cell centres.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F

from radar2shape.nn.kernels import fast_enabled

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


@dataclass(frozen=True)
class PlaneCells:
    """The cells of a point set on the three planes, flattened over (shape, plane, cell), computed once
    per level and shared by every pooling of that level (the cell counts do not depend on features).

    ``flat [3, B*N]``: row of each point's cell on each plane in a ``[B*3*R*R, C]`` table;
    ``count [B*3*R*R]``: points per cell (at least 1, so empty cells read 0);
    ``inv_count [3, B*N]``: 1 / points in each point's cell.
    """

    flat: torch.Tensor
    count: torch.Tensor
    inv_count: torch.Tensor
    batch: int
    resolution: int

    @classmethod
    def from_index(cls, index: torch.Tensor, resolution: int) -> PlaneCells:
        b, _, n = index.shape
        cells = resolution * resolution
        offset = torch.arange(b * 3, device=index.device).reshape(b, 3, 1) * cells
        flat = (index + offset).permute(1, 0, 2).reshape(3, b * n)
        count = torch.bincount(flat.reshape(-1), minlength=b * 3 * cells).clamp(min=1).float()
        return cls(flat, count, 1.0 / count[flat], b, int(resolution))

    def sums(self, features: torch.Tensor) -> torch.Tensor:
        """Per-cell sums ``[B*3*R*R, C]`` of ``features [B, N, C]``."""
        c = features.shape[-1]
        flat_features = features.reshape(-1, c)
        out = flat_features.new_zeros(self.batch * 3 * self.resolution**2, c)
        for p in range(3):
            out.index_add_(0, self.flat[p], flat_features)
        return out


def project_to_planes(features: torch.Tensor, index: torch.Tensor, resolution: int,
                      cells: PlaneCells | None = None) -> torch.Tensor:
    """Mean-pool point features ``[B, N, C]`` onto the planes given ``index [B, 3, N]``: ``[B, 3, C, R, R]``."""
    b, _, c = features.shape
    if fast_enabled():
        cells = cells or PlaneCells.from_index(index, resolution)
        means = cells.sums(features) / cells.count[:, None].to(features.dtype)
        return means.reshape(b, 3, resolution, resolution, c).permute(0, 1, 4, 2, 3).contiguous()
    planes = [scatter_mean(features, index[:, p], resolution * resolution) for p in range(3)]
    return torch.stack(planes, dim=1).reshape(b, 3, c, resolution, resolution)


def local_pool(features: torch.Tensor, index: torch.Tensor, resolution: int,
               cells: PlaneCells | None = None) -> torch.Tensor:
    """Each point gets the mean feature of its cell, summed over the three planes: ``[B, N, C]``.

    ConvONet's local pooling (scatter-then-gather), which lets a per-point network see its
    neighbourhood at the level's resolution without any nearest-neighbour search.
    """
    c = features.shape[-1]
    if fast_enabled():
        cells = cells or PlaneCells.from_index(index, resolution)
        sums = cells.sums(features)
        pooled = sum(sums.index_select(0, cells.flat[p]) * cells.inv_count[p, :, None].to(sums.dtype) for p in range(3))
        return pooled.reshape(features.shape)
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
