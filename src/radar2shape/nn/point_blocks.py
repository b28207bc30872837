"""Per-point ResNet blocks with ConvONet-style local pooling on feature planes."""

from __future__ import annotations

import torch
from torch import nn

from radar2shape.nn.triplane import PlaneCells, local_pool


class ResnetBlockFC(nn.Module):
    """Two-layer fully connected residual block on the last axis (ConvONet / Occupancy Networks).

    The second layer starts at zero so a fresh block is the identity (or the linear shortcut),
    which keeps deep point networks stable from the first step.
    """

    def __init__(self, size_in: int, size_out: int | None = None, size_hidden: int | None = None) -> None:
        super().__init__()
        size_out = size_in if size_out is None else size_out
        size_hidden = min(size_in, size_out) if size_hidden is None else size_hidden
        self.fc_0 = nn.Linear(size_in, size_hidden)
        self.fc_1 = nn.Linear(size_hidden, size_out)
        self.act = nn.ReLU()
        self.shortcut = nn.Linear(size_in, size_out, bias=False) if size_in != size_out else nn.Identity()
        nn.init.zeros_(self.fc_1.weight)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        dx = self.fc_1(self.act(self.fc_0(self.act(x))))
        return self.shortcut(x) + dx


class LocalPoolPointNet(nn.Module):
    """``n_blocks`` ResNet point blocks; before every block after the first, each point's feature is
    concatenated with its locally pooled feature (mean over its plane cell, summed over planes).

    Input ``[B, N, width]`` and the points' plane cell indices ``[B, 3, N]`` at ``resolution``.
    """

    def __init__(self, width: int, n_blocks: int, resolution: int) -> None:
        super().__init__()
        if n_blocks < 1:
            raise ValueError(f"n_blocks must be >= 1, got {n_blocks}")
        self.resolution = int(resolution)
        self.blocks = nn.ModuleList([ResnetBlockFC(width)] + [ResnetBlockFC(2 * width, width) for _ in range(n_blocks - 1)])

    def forward(self, features: torch.Tensor, index: torch.Tensor, cells: PlaneCells | None = None) -> torch.Tensor:
        net = self.blocks[0](features)
        for block in self.blocks[1:]:
            net = block(torch.cat([net, local_pool(net, index, self.resolution, cells)], dim=-1))
        return net
