"""A timestep-conditioned 1D U-Net over a sequence axis (the aspect angle of a roll-symmetric radar).

The roll-symmetric denoiser (docs/design.md section 2) convolves along aspect, with the radar's
frequencies and the encoded noisy profile as channels. Each residual block adds a projection of the
timestep embedding to its feature maps (the DDPM recipe, Ho et al. 2020), so every resolution knows
the noise level. Lengths that are not a multiple of ``2**depth`` are zero-padded and cropped back.
"""

from __future__ import annotations

import math

import torch
from torch import nn
from torch.nn import functional as F

from radar2shape.nn.positional import TimestepEmbedding


def _norm(channels: int) -> nn.GroupNorm:
    return nn.GroupNorm(math.gcd(8, channels), channels)


class ResBlock1D(nn.Module):
    """Conv-Norm-SiLU twice with the timestep embedding added in between, plus a 1x1 skip."""

    def __init__(self, c_in: int, c_out: int, time_dim: int) -> None:
        super().__init__()
        self.conv1 = nn.Conv1d(c_in, c_out, 3, padding=1)
        self.norm1 = _norm(c_out)
        self.time = nn.Linear(time_dim, c_out)
        self.conv2 = nn.Conv1d(c_out, c_out, 3, padding=1)
        self.norm2 = _norm(c_out)
        self.skip = nn.Identity() if c_in == c_out else nn.Conv1d(c_in, c_out, 1)

    def forward(self, x: torch.Tensor, t_emb: torch.Tensor) -> torch.Tensor:
        h = F.silu(self.norm1(self.conv1(x)))
        h = h + self.time(t_emb)[:, :, None]
        h = F.silu(self.norm2(self.conv2(h)))
        return h + self.skip(x)


class UNet1D(nn.Module):
    """``x [B, in_channels, L]``, timesteps ``t [B]`` -> ``[B, out_channels, L]``.

    Args:
        base_channels: width of the first level; it doubles per level up to ``max_channels``.
        depth: number of 2x downsamplings (0 = one residual block, no pooling).
        time_dim: width of the sinusoidal timestep embedding shared by all blocks.
    """

    def __init__(
        self,
        in_channels: int,
        out_channels: int,
        base_channels: int = 32,
        depth: int = 2,
        max_channels: int = 256,
        time_dim: int = 64,
    ) -> None:
        super().__init__()
        self.depth = depth
        widths = [min(base_channels * 2**i, max_channels) for i in range(depth + 1)]
        self.time_embedding = TimestepEmbedding(time_dim)
        self.stem = nn.Conv1d(in_channels, widths[0], 3, padding=1)
        self.down = nn.ModuleList(ResBlock1D(widths[max(i - 1, 0)], widths[i], time_dim) for i in range(depth + 1))
        self.up = nn.ModuleList(nn.ConvTranspose1d(widths[i + 1], widths[i], 2, stride=2) for i in reversed(range(depth)))
        self.merge = nn.ModuleList(ResBlock1D(2 * widths[i], widths[i], time_dim) for i in reversed(range(depth)))
        self.head = nn.Conv1d(widths[0], out_channels, 1)

    def forward(self, x: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        length = x.shape[-1]
        multiple = 2**self.depth
        x = F.pad(x, (0, (-length) % multiple))
        t_emb = self.time_embedding(t)
        x = self.stem(x)
        skips = []
        for i, block in enumerate(self.down):
            x = block(x if i == 0 else F.max_pool1d(x, 2), t_emb)
            skips.append(x)
        skips.pop()
        for up, merge in zip(self.up, self.merge):
            x = merge(torch.cat([up(x), skips.pop()], dim=1), t_emb)
        return self.head(x)[..., :length]
