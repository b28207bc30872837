"""A small 2D U-Net (Ronneberger et al. 2015) whose depth is chosen to fit the input resolution."""

from __future__ import annotations

import math

import torch
from torch import nn


def conv_block(c_in: int, c_out: int) -> nn.Sequential:
    """Two 3x3 convolutions with GroupNorm + ReLU (GroupNorm: batch-size independent)."""
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, padding=1),
        nn.GroupNorm(math.gcd(8, c_out), c_out),
        nn.ReLU(inplace=True),
        nn.Conv2d(c_out, c_out, 3, padding=1),
        nn.GroupNorm(math.gcd(8, c_out), c_out),
        nn.ReLU(inplace=True),
    )


def depth_for_resolution(resolution: int, min_resolution: int = 4, max_depth: int = 4) -> int:
    """Number of 2x downsamplings that keep the bottleneck at ``>= min_resolution`` pixels."""
    depth = 0
    while depth < max_depth and resolution % 2 == 0 and resolution // 2 >= min_resolution:
        resolution //= 2
        depth += 1
    return depth


class UNet2D(nn.Module):
    """``[B, in_channels, H, W] -> [B, out_channels, H, W]``; ``H`` and ``W`` divisible by ``2**depth``.

    Channels double per level from ``base_channels`` up to ``max_channels``; ``depth=0`` is a plain
    conv block. Upsampling by transposed convolution, skips by concatenation.
    """

    def __init__(
        self, in_channels: int, out_channels: int, base_channels: int = 32, depth: int = 3, max_channels: int = 256
    ) -> None:
        super().__init__()
        widths = [min(base_channels * 2**i, max_channels) for i in range(depth + 1)]
        self.down = nn.ModuleList([conv_block(in_channels, widths[0])])
        self.down.extend(conv_block(widths[i], widths[i + 1]) for i in range(depth))
        self.pool = nn.MaxPool2d(2)
        self.up = nn.ModuleList(nn.ConvTranspose2d(widths[i + 1], widths[i], 2, stride=2) for i in reversed(range(depth)))
        self.merge = nn.ModuleList(conv_block(2 * widths[i], widths[i]) for i in reversed(range(depth)))
        self.head = nn.Conv2d(widths[0], out_channels, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        skips = []
        for i, block in enumerate(self.down):
            x = block(x if i == 0 else self.pool(x))
            skips.append(x)
        skips.pop()
        for up, merge in zip(self.up, self.merge):
            x = merge(torch.cat([up(x), skips.pop()], dim=1))
        return self.head(x)
