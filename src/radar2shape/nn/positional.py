"""Sine-cosine encodings of integer positions: radar-block index and diffusion timestep.

One function serves both, so a block index ``j`` and a timestep ``t`` are encoded the same way
(Vaswani et al. 2017); the timestep gets a small MLP on top, as in DDPM implementations.
"""

from __future__ import annotations

import math

import torch
from torch import nn


def sinusoidal_embedding(positions: torch.Tensor, dim: int, max_period: float = 10000.0) -> torch.Tensor:
    """Positions ``[...]`` -> ``[..., dim]``: ``[sin(p w_i), cos(p w_i)]`` with ``w_i`` geometric in ``i``.

    The wavelengths run from ``2 pi`` to ``2 pi * max_period``, so nearby positions get similar codes
    and far ones distinct codes; an odd ``dim`` gets one zero column.
    """
    half = dim // 2
    freqs = torch.exp(-math.log(max_period) * torch.arange(half, device=positions.device, dtype=torch.float32) / half)
    args = positions.to(torch.float32)[..., None] * freqs
    embedding = torch.cat([torch.sin(args), torch.cos(args)], dim=-1)
    if dim % 2:
        embedding = nn.functional.pad(embedding, (0, 1))
    return embedding


class TimestepEmbedding(nn.Module):
    """Diffusion timestep ``t [B]`` (integers) -> ``[B, dim]``: sinusoid, then Linear-SiLU-Linear."""

    def __init__(self, dim: int, hidden: int | None = None) -> None:
        super().__init__()
        self.dim = dim
        hidden = hidden or 4 * dim
        self.mlp = nn.Sequential(nn.Linear(dim, hidden), nn.SiLU(), nn.Linear(hidden, dim))

    def forward(self, t: torch.Tensor) -> torch.Tensor:
        return self.mlp(sinusoidal_embedding(t, self.dim))
