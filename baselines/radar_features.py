"""Radar -> feature maps over (aspect, roll) plus one global vector, for the single-view baselines.

TMNet and LIST were designed around an image encoder. Here the "image" is the whole dB response:
all frequencies as channels plus the observability mask (so "unobserved" differs from "0 dB"),
through the project's ResNet (:class:`radar2shape.nn.radar_encoder.ResNetEncoder`). The baselines
thus get the same radar network as Radar2Shape and differ only in how they decode a shape.
"""

from __future__ import annotations

import torch
from torch import nn

from radar2shape.errors import UserInputError
from radar2shape.nn.radar_encoder import ResNetEncoder


def radar_image(radar: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Radar ``[B, A, R, F]`` and mask ``[B, A, R]`` -> image ``[B, F + 1, A, R]`` (mask last)."""
    if radar.dim() != 4 or mask.shape != radar.shape[:3]:
        raise UserInputError(f"radar must be [B, A, R, F] with mask [B, A, R], got {tuple(radar.shape)} and {tuple(mask.shape)}")
    return torch.cat([radar.permute(0, 3, 1, 2), mask.to(radar.dtype)[:, None]], dim=1)


def _downsamples(layer: nn.Module) -> bool:
    """True for a layer holding a strided convolution: the first block of a new ResNet stage."""
    return any(isinstance(m, nn.Conv2d) and m.stride != (1, 1) for m in layer.modules())


class RadarFeatures(nn.Module):
    """``(radar, mask) -> (maps, vector)``: the last feature map of each ResNet stage
    (``[B, C_s, A_s, R_s]``, finest first) and the pooled global feature ``[B, dim]``.

    Stages are split where the network downsamples, so the number of maps does not depend on the
    input size; ``map_channels`` lists ``C_s``.
    """

    def __init__(self, n_freq: int, dim: int, depth: int = 18, width_mult: float = 1.0) -> None:
        super().__init__()
        self.n_freq = int(n_freq)
        self.resnet = ResNetEncoder(self.n_freq + 1, dim, depth, width_mult)
        with torch.no_grad():
            maps = self._stage_maps(torch.zeros(1, self.n_freq + 1, 16, 16))
        self.map_channels = [m.shape[1] for m in maps]

    def _stage_maps(self, x: torch.Tensor) -> list[torch.Tensor]:
        maps: list[torch.Tensor] = []
        for layer in self.resnet.features:
            if _downsamples(layer):
                maps.append(x)  # the output of the stage that ends here
            x = layer(x)
        return maps + [x]

    def forward(self, radar: torch.Tensor, mask: torch.Tensor) -> tuple[list[torch.Tensor], torch.Tensor]:
        if radar.shape[-1] != self.n_freq:
            raise UserInputError(f"model expects {self.n_freq} radar frequencies, got radar of shape {tuple(radar.shape)}")
        maps = self._stage_maps(radar_image(radar, mask))
        return maps, self.resnet.head(maps[-1].mean(dim=(-2, -1)))
