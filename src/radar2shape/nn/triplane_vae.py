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

from collections.abc import Mapping
from dataclasses import dataclass, fields

import torch
from torch import nn

from radar2shape.nn.hash_encoding import HashEncoding
from radar2shape.nn.mlp import MLP
from radar2shape.nn.plane_vae import PlaneDecoder, PlanePosterior
from radar2shape.nn.point_blocks import LocalPoolPointNet
from radar2shape.nn.kernels import fast_enabled
from radar2shape.nn.triplane import PlaneCells, plane_cell_index, project_to_planes, sample_planes
from radar2shape.nn.unet2d import UNet2D, depth_for_resolution


@dataclass(frozen=True)
class TriplaneVAESizes:
    """Every size of the encoder and decoder in one place (see :class:`radar2shape.models.sdf_vae.SDFVAE`)."""

    resolutions: tuple[int, ...]
    hash_features: int
    log2_hashmap_size: int
    hash_init_scale: float
    width: int
    n_blocks: int
    plane_channels: int
    unet_channels: int
    unet_max_depth: int
    latent_dim: int
    vae_hidden: int
    mlp_hidden: int
    mlp_layers: int
    bound: float
    init_logvar: float

    @classmethod
    def from_dict(cls, values: Mapping) -> TriplaneVAESizes:
        """The sizes among ``values`` (e.g. a module's hparams); other keys are ignored."""
        sizes = {f.name: values[f.name] for f in fields(cls)}
        return cls(**{**sizes, "resolutions": tuple(int(r) for r in sizes["resolutions"])})


class LevelEncoder(nn.Module):
    """One level: hash features + xyz of the surface points -> posterior (mu, logvar) ``[B, Z]``."""

    def __init__(self, sizes: TriplaneVAESizes, resolution: int) -> None:
        super().__init__()
        self.resolution = resolution
        self.bound = sizes.bound
        self.fc_in = nn.Linear(sizes.hash_features + 3, sizes.width)
        self.points = LocalPoolPointNet(sizes.width, sizes.n_blocks, resolution)
        self.fc_out = nn.Linear(sizes.width, sizes.plane_channels)
        depth = depth_for_resolution(resolution, max_depth=sizes.unet_max_depth)
        self.unet = UNet2D(sizes.plane_channels, sizes.plane_channels, sizes.unet_channels, depth)
        self.posterior = PlanePosterior(
            sizes.plane_channels, resolution, sizes.latent_dim, sizes.vae_hidden, sizes.init_logvar
        )

    def forward(self, points: torch.Tensor, hash_features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        index = plane_cell_index(points, self.resolution, self.bound)  # [B, 3, N]
        cells = PlaneCells.from_index(index, self.resolution) if fast_enabled() else None
        net = self.points(self.fc_in(torch.cat([hash_features, points], dim=-1)), index, cells)
        planes = project_to_planes(self.fc_out(net), index, self.resolution, cells)  # [B, 3, C, R, R]
        b, _, c, r, _ = planes.shape
        planes = self.unet(planes.reshape(b * 3, c, r, r)).reshape(b, 3, c, r, r)
        return self.posterior(planes)


class MultiresTriplaneEncoder(nn.Module):
    """Surface points ``[B, N, 3]`` -> posterior mean and log-variance ``[B, L, Z]``."""

    def __init__(self, sizes: TriplaneVAESizes) -> None:
        super().__init__()
        self.hash = HashEncoding(
            sizes.resolutions, sizes.hash_features, sizes.log2_hashmap_size, sizes.bound, sizes.hash_init_scale
        )
        self.levels = nn.ModuleList(LevelEncoder(sizes, r) for r in sizes.resolutions)

    def forward(self, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        feats = self.hash(points)  # [B, N, L, F]
        posteriors = [level(points, feats[:, :, l]) for l, level in enumerate(self.levels)]
        mu, logvar = zip(*posteriors)
        return torch.stack(mu, dim=1), torch.stack(logvar, dim=1)


class MultiresTriplaneDecoder(nn.Module):
    """Latent ``[B, L, Z]`` -> per-level triplanes -> SDF at query points."""

    def __init__(self, sizes: TriplaneVAESizes) -> None:
        super().__init__()
        self.bound = sizes.bound
        self.levels = nn.ModuleList(
            PlaneDecoder(sizes.latent_dim, r, sizes.plane_channels, sizes.vae_hidden) for r in sizes.resolutions
        )
        self.mlp = MLP(sizes.plane_channels + 3, sizes.mlp_hidden, sizes.mlp_layers, 1)

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
