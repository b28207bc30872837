"""Encoder and decoder networks of the hierarchical multiresolution triplane SDF-VAE (Stage 1).

Shapes (B shapes, N surface points, Q queries, L levels, level resolutions R_l, latent size Z):

    encoder: points [B, N, 3]
      -> hash features [B, N, L, F]                       (one lattice per level, R_l vertices)
      -> per level l: linear([feat_l, xyz]) [B, N, H]     (xyz added so a fresh, near-zero hash
                                                           table still tells where each point is)
      -> ResNet point blocks + local pooling at R_l       [B, N, H]
      -> linear to C, mean projection on xy/xz/yz         [B, 3, C, R_l, R_l]
      -> 2D U-Net (shared by the three planes)            [B, 3, C, R_l, R_l]
      -> posterior head                                   mu_l, logvar_l [B, Z]
    stacked over levels: mu, logvar [B, L, Z]

    decoder: h [B, L, Z] -> per level: triplane [B, 3, C, R_l, R_l]
      -> bilinear read at queries, summed over planes and levels [B, Q, C]
      -> MLP([features, xyz]) -> sdf [B, Q]

Levels never mix before the decoder's sum, so each h_l is a separate token for Stage 2.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn

from radar2shape.nn.hash_encoding import HashEncoding
from radar2shape.nn.mlp import MLP
from radar2shape.nn.plane_vae import PlaneDecoder, PlanePosterior
from radar2shape.nn.point_blocks import LocalPoolPointNet
from radar2shape.nn.triplane import plane_cell_index, project_to_planes, sample_planes
from radar2shape.nn.unet2d import UNet2D, depth_for_resolution


class LevelEncoder(nn.Module):
    """One level: hash features + xyz of the surface points -> posterior (mu, logvar) ``[B, Z]``."""

    def __init__(
        self,
        resolution: int,
        hash_features: int,
        width: int,
        n_blocks: int,
        plane_channels: int,
        unet_channels: int,
        unet_max_depth: int,
        latent_dim: int,
        vae_hidden: int,
        bound: float,
        init_logvar: float,
    ) -> None:
        super().__init__()
        self.resolution = resolution
        self.bound = bound
        self.fc_in = nn.Linear(hash_features + 3, width)
        self.points = LocalPoolPointNet(width, n_blocks, resolution)
        self.fc_out = nn.Linear(width, plane_channels)
        depth = depth_for_resolution(resolution, max_depth=unet_max_depth)
        self.unet = UNet2D(plane_channels, plane_channels, unet_channels, depth)
        self.posterior = PlanePosterior(plane_channels, resolution, latent_dim, vae_hidden, init_logvar)

    def forward(self, points: torch.Tensor, hash_features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        index = plane_cell_index(points, self.resolution, self.bound)  # [B, 3, N]
        net = self.points(self.fc_in(torch.cat([hash_features, points], dim=-1)), index)
        planes = project_to_planes(self.fc_out(net), index, self.resolution)  # [B, 3, C, R, R]
        b, _, c, r, _ = planes.shape
        planes = self.unet(planes.reshape(b * 3, c, r, r)).reshape(b, 3, c, r, r)
        return self.posterior(planes)


class MultiresTriplaneEncoder(nn.Module):
    """Surface points ``[B, N, 3]`` -> posterior mean and log-variance ``[B, L, Z]``."""

    def __init__(
        self,
        resolutions: Sequence[int],
        hash_features: int,
        log2_hashmap_size: int,
        hash_init_scale: float,
        width: int,
        n_blocks: int,
        plane_channels: int,
        unet_channels: int,
        unet_max_depth: int,
        latent_dim: int,
        vae_hidden: int,
        bound: float,
        init_logvar: float,
    ) -> None:
        super().__init__()
        self.hash = HashEncoding(resolutions, hash_features, log2_hashmap_size, bound, hash_init_scale)
        self.levels = nn.ModuleList(
            LevelEncoder(
                r, hash_features, width, n_blocks, plane_channels, unet_channels, unet_max_depth,
                latent_dim, vae_hidden, bound, init_logvar,
            )
            for r in resolutions
        )

    def forward(self, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        feats = self.hash(points)  # [B, N, L, F]
        posteriors = [level(points, feats[:, :, l]) for l, level in enumerate(self.levels)]
        mu, logvar = zip(*posteriors)
        return torch.stack(mu, dim=1), torch.stack(logvar, dim=1)


class MultiresTriplaneDecoder(nn.Module):
    """Latent ``[B, L, Z]`` -> per-level triplanes -> SDF at query points."""

    def __init__(
        self,
        resolutions: Sequence[int],
        latent_dim: int,
        plane_channels: int,
        vae_hidden: int,
        mlp_hidden: int,
        mlp_layers: int,
        bound: float,
    ) -> None:
        super().__init__()
        self.bound = bound
        self.levels = nn.ModuleList(PlaneDecoder(latent_dim, r, plane_channels, vae_hidden) for r in resolutions)
        self.mlp = MLP(plane_channels + 3, mlp_hidden, mlp_layers, 1)

    def decode_planes(self, h: torch.Tensor) -> list[torch.Tensor]:
        """Per-level triplanes ``[B, 3, C, R_l, R_l]`` from ``h [B, L, Z]`` (decode once, query often)."""
        return [level(h[:, l]) for l, level in enumerate(self.levels)]

    def query(self, planes: list[torch.Tensor], queries: torch.Tensor, level_mask: torch.Tensor | None = None) -> torch.Tensor:
        """SDF ``[B, Q]`` at ``queries [B, Q, 3]`` from decoded triplanes.

        ``level_mask [B, L]`` (optional) weights each level's features, 0 drops a level.
        """
        feats = [sample_planes(p, queries, self.bound) for p in planes]
        if level_mask is not None:
            feats = [f * level_mask[:, l, None, None] for l, f in enumerate(feats)]
        return self.mlp(torch.cat([sum(feats), queries], dim=-1)).squeeze(-1)

    def forward(self, h: torch.Tensor, queries: torch.Tensor, level_mask: torch.Tensor | None = None) -> torch.Tensor:
        return self.query(self.decode_planes(h), queries, level_mask)
