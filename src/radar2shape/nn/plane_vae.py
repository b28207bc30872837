"""The per-level VAE bottleneck between a triplane and a flat latent vector.

A latent vector (rather than a latent triplane) is what the Stage-2 Transformer needs: one token
``h_l in R^Z`` per level. Planes are compressed by stride-2 convolutions down to a ``4 x 4`` map,
flattened and projected (Diffusion-SDF's VAE does the same at one scale); the decoder mirrors it
with bilinear upsampling + 3x3 convolutions (no checkerboard artefacts of transposed convs).
"""

from __future__ import annotations

import torch
from torch import nn

from radar2shape.nn.unet2d import depth_for_resolution

BOTTLENECK = 4  # spatial size of the flattened map


def _check_resolution(resolution: int) -> int:
    if resolution < 1 or resolution & (resolution - 1):
        raise ValueError(f"plane resolution must be a power of two, got {resolution}")
    return depth_for_resolution(resolution, min_resolution=BOTTLENECK, max_depth=16)


class PlanePosterior(nn.Module):
    """Triplane ``[B, 3, C, R, R]`` -> posterior mean and log-variance ``[B, Z]`` each.

    ``init_logvar``: starting value of the log-variance bias; a small posterior variance at
    the start keeps the sampling noise from drowning the untrained latent.
    """

    def __init__(self, channels: int, resolution: int, latent_dim: int, hidden: int, init_logvar: float = 0.0) -> None:
        super().__init__()
        n_down = _check_resolution(resolution)
        size = resolution // 2**n_down
        layers: list[nn.Module] = [nn.Conv2d(3 * channels, hidden, 3, padding=1), nn.ReLU(inplace=True)]
        for _ in range(n_down):
            layers += [nn.Conv2d(hidden, hidden, 3, stride=2, padding=1), nn.ReLU(inplace=True)]
        layers.append(nn.Flatten())
        self.features = nn.Sequential(*layers)
        self.fc_mu = nn.Linear(hidden * size * size, latent_dim)
        self.fc_logvar = nn.Linear(hidden * size * size, latent_dim)
        nn.init.constant_(self.fc_logvar.bias, init_logvar)

    def forward(self, planes: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        feat = self.features(planes.flatten(1, 2))
        return self.fc_mu(feat), self.fc_logvar(feat)


class PlaneDecoder(nn.Module):
    """Latent ``[B, Z]`` -> triplane ``[B, 3, C, R, R]``."""

    def __init__(self, latent_dim: int, resolution: int, channels: int, hidden: int) -> None:
        super().__init__()
        n_up = _check_resolution(resolution)
        self.size = resolution // 2**n_up
        self.hidden = hidden
        self.channels = channels
        self.fc = nn.Linear(latent_dim, hidden * self.size * self.size)
        layers: list[nn.Module] = []
        for _ in range(n_up):
            layers += [
                nn.Upsample(scale_factor=2, mode="bilinear", align_corners=False),
                nn.Conv2d(hidden, hidden, 3, padding=1),
                nn.ReLU(inplace=True),
            ]
        layers.append(nn.Conv2d(hidden, 3 * channels, 3, padding=1))
        self.upsample = nn.Sequential(*layers)

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        x = torch.relu(self.fc(h)).reshape(-1, self.hidden, self.size, self.size)
        planes = self.upsample(x)
        return planes.reshape(h.shape[0], 3, self.channels, *planes.shape[-2:])
