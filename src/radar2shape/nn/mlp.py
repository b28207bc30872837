"""Plain fully connected network, the SDF head of the decoders."""

from __future__ import annotations

import torch
from torch import nn


class MLP(nn.Module):
    """``[..., in_features] -> [..., out_features]`` through ``n_hidden`` ReLU layers of ``hidden`` units."""

    def __init__(self, in_features: int, hidden: int, n_hidden: int, out_features: int = 1) -> None:
        super().__init__()
        widths = [in_features] + [hidden] * n_hidden
        layers: list[nn.Module] = []
        for w_in, w_out in zip(widths[:-1], widths[1:]):
            layers += [nn.Linear(w_in, w_out), nn.ReLU(inplace=True)]
        layers.append(nn.Linear(widths[-1], out_features))
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)
