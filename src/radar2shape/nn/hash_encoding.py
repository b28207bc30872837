"""Multiresolution hash encoding (Muller et al. 2022, Instant-NGP) in pure PyTorch.

Pure PyTorch rather than tiny-cuda-nn so the encoder runs on CPU, on any GPU and under
``torch.compile`` without a compiled extension. Each level is one learned feature lattice of
``R`` vertices per axis over the cube ``[-bound, bound]^3``:

- dense path when the lattice fits the table (``R**3 <= 2**log2_table_size``): a ``[F, R, R, R]``
  grid read with ``F.grid_sample`` (trilinear, ``align_corners=True``), the fastest form;
- hashed path otherwise: a ``[2**T, F]`` table indexed by the Instant-NGP spatial hash
  (``i * 1 XOR j * 2654435761 XOR k * 805459861 mod 2**T``) and interpolated explicitly over the
  8 corners of the point's cell.

Both paths read the same lattice convention, exposed by :meth:`HashEncoding.vertex_features`,
so one brute-force trilinear reference checks either.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
import torch.nn.functional as F
from torch import nn

HASH_PRIMES = (1, 2654435761, 805459861)
_CORNERS = torch.tensor([[dx, dy, dz] for dz in (0, 1) for dy in (0, 1) for dx in (0, 1)])


def spatial_hash(ijk: torch.Tensor, log2_table_size: int) -> torch.Tensor:
    """Instant-NGP hash of integer vertex coordinates ``ijk [..., 3]`` into ``[0, 2**T)``."""
    ijk = ijk.long()
    h = ijk[..., 0] * HASH_PRIMES[0]
    h = h ^ (ijk[..., 1] * HASH_PRIMES[1])
    h = h ^ (ijk[..., 2] * HASH_PRIMES[2])
    return h & ((1 << log2_table_size) - 1)


class HashEncoding(nn.Module):
    """Points ``[..., 3]`` in ``[-bound, bound]^3`` -> features ``[..., L, F]``, one set per level.

    ``resolutions`` are lattice vertex counts per axis (level ``l`` has spacing
    ``2 * bound / (R_l - 1)``). Points outside the cube are clamped onto its faces.
    ``init_scale``: tables start uniform in ``[-init_scale, init_scale]`` (Instant-NGP: 1e-4).
    """

    def __init__(
        self,
        resolutions: Sequence[int],
        features_per_level: int = 2,
        log2_table_size: int = 19,
        bound: float = 0.5,
        init_scale: float = 1e-4,
    ) -> None:
        super().__init__()
        if any(int(r) < 2 for r in resolutions):
            raise ValueError(f"hash encoding resolutions must be >= 2 vertices per axis, got {list(resolutions)}")
        self.resolutions = [int(r) for r in resolutions]
        self.features_per_level = int(features_per_level)
        self.log2_table_size = int(log2_table_size)
        self.bound = float(bound)
        self.tables = nn.ParameterList()
        for res in self.resolutions:
            shape = (self.features_per_level, res, res, res) if self.is_dense(res) else (1 << self.log2_table_size, self.features_per_level)
            self.tables.append(nn.Parameter(torch.empty(shape).uniform_(-init_scale, init_scale)))

    @property
    def n_levels(self) -> int:
        return len(self.resolutions)

    def is_dense(self, resolution: int) -> bool:
        """True when a level's full lattice fits the table, so no hashing (and no collisions)."""
        return resolution**3 <= (1 << self.log2_table_size)

    def lattice_coords(self, points: torch.Tensor, level: int) -> torch.Tensor:
        """Continuous lattice coordinates in ``[0, R - 1]`` of ``points [..., 3]`` at ``level``."""
        unit = ((points + self.bound) / (2 * self.bound)).clamp(0.0, 1.0)
        return unit * (self.resolutions[level] - 1)

    def vertex_features(self, level: int, ijk: torch.Tensor) -> torch.Tensor:
        """Feature ``[..., F]`` stored at integer lattice vertices ``ijk [..., 3]`` (x, y, z order)."""
        table = self.tables[level]
        if self.is_dense(self.resolutions[level]):
            # grid_sample convention: the grid is indexed [F, z, y, x].
            return table[:, ijk[..., 2], ijk[..., 1], ijk[..., 0]].movedim(0, -1)
        # index_select, not table[ids]: its backward (index_add_) sums in a fixed order, where
        # indexing's backward (index_put_ with accumulate) adds from several threads at once.
        ids = spatial_hash(ijk, self.log2_table_size)
        return table.index_select(0, ids.reshape(-1)).reshape(*ids.shape, table.shape[-1])

    def _dense_level(self, points: torch.Tensor, level: int) -> torch.Tensor:
        grid = (self.lattice_coords(points, level) / (self.resolutions[level] - 1)) * 2 - 1
        sampled = F.grid_sample(
            self.tables[level][None], grid.reshape(1, 1, 1, -1, 3), mode="bilinear", align_corners=True
        )
        return sampled.reshape(self.features_per_level, -1).T

    def _hashed_level(self, points: torch.Tensor, level: int) -> torch.Tensor:
        pos = self.lattice_coords(points, level)
        base = pos.floor().clamp(max=self.resolutions[level] - 2)
        frac = pos - base
        corners = _CORNERS.to(points.device)  # [8, 3]
        ijk = base.long()[:, None, :] + corners  # [N, 8, 3]
        weights = torch.where(corners.bool(), frac[:, None, :], 1 - frac[:, None, :]).prod(-1)  # [N, 8]
        return (self.vertex_features(level, ijk) * weights[..., None]).sum(1)

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        flat = points.reshape(-1, 3)
        levels = [
            self._dense_level(flat, l) if self.is_dense(r) else self._hashed_level(flat, l)
            for l, r in enumerate(self.resolutions)
        ]
        return torch.stack(levels, dim=-2).reshape(*points.shape[:-1], self.n_levels, self.features_per_level)
