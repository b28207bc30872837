"""LIST baseline (Arshad & Beksi 2023, "LIST: Learning Implicitly from Spatial Transformers for
Single-View 3D Reconstruction"), conditioned on radar instead of an image.

Per shape, from the radar feature maps and global feature ``z`` (:class:`baselines.radar_features.RadarFeatures`):

1. coarse predictor: ``z`` -> a coarse point cloud ``[P, 3]`` (trained by Chamfer to the surface);
2. localisation: LIST's spatial transformer replaces camera projection; here each query point
   ``q`` starts at the radar cell that looks along its direction from the centre
   (aspect ``acos(q_z / |q|)``, roll ``atan2(q_y, q_x)``: where the radar sees surface facing
   that way specularly), and an MLP on ``[q, z, cloud context]`` predicts ``K`` offsets from that
   cell and attention weights over them; the feature maps are sampled there and averaged;
3. SDF decoder: MLP on ``[q, local features, z, cloud context]`` -> signed distance.

Cloud context of a query: a PointNet (max-pooled) feature of the coarse cloud plus the offset
to, and distance from, its nearest coarse point. The coarse cloud is detached for the context,
so it learns from its Chamfer loss only. Loss: truncated L1 on SDF samples (the Stage-1 loss of
:mod:`radar2shape.models.sdf_vae`) + ``w_coarse`` * coarse Chamfer.
"""

from __future__ import annotations

import math

import torch
from torch import nn
from torch.nn import functional as F

from baselines.point_losses import chamfer_l2, nearest
from baselines.radar_features import RadarFeatures
from radar2shape.models.base import Reconstruction, ReconstructionModel
from radar2shape.models.sdf_vae import truncated_l1
from radar2shape.nn.kernels import fast_enabled
from radar2shape.nn.mlp import MLP


def split_mlp(mlp: MLP, per_query: torch.Tensor, per_shape: torch.Tensor, start: int) -> torch.Tensor:
    """``mlp`` on ``[per_query[..., :start], per_shape (broadcast over queries), per_query[..., start:]]``.

    The per-shape columns of the first layer are applied once per shape and added as a bias,
    instead of being copied to every query and multiplied there: same function, and the widest
    part of the first layer's matmul and of its input drops out (forward and backward).
    """
    first = mlp.net[0]
    width = per_shape.shape[-1]
    w_query = torch.cat([first.weight[:, :start], first.weight[:, start + width:]], dim=1)
    bias = F.linear(per_shape, first.weight[:, start:start + width], first.bias)  # [B, H]
    return mlp.net[1:](F.linear(per_query, w_query) + bias[:, None])


def radar_coordinates(points: torch.Tensor) -> torch.Tensor:
    """``grid_sample`` coordinates ``[..., 2]`` (x: roll over [0, 2 pi), y: aspect over [0, pi]) of each point's direction."""
    aspect = torch.atan2(points[..., :2].norm(dim=-1), points[..., 2])  # acos(z / |q|), defined at 0
    roll = torch.atan2(points[..., 1], points[..., 0]) % (2 * math.pi)
    return torch.stack([roll / math.pi - 1, aspect / (math.pi / 2) - 1], dim=-1)


class ShapeContext:
    """What one batch's radar gives every query: feature maps, global feature, coarse cloud and its PointNet feature."""

    def __init__(self, maps: list[torch.Tensor], z: torch.Tensor, coarse: torch.Tensor, cloud: torch.Tensor) -> None:
        self.maps, self.z, self.coarse, self.cloud = maps, z, coarse, cloud

    def select(self, i: int) -> ShapeContext:
        """The context of shape ``i`` alone (batch of one)."""
        return ShapeContext([m[i : i + 1] for m in self.maps], self.z[i : i + 1], self.coarse[i : i + 1], self.cloud[i : i + 1])


class LIST(ReconstructionModel):
    """Coarse cloud + spatially transformed local radar features -> SDF; meshes by marching cubes.

    Args (primitive, so checkpoints load with ``torch.load(weights_only=True)``):
        num_freq: radar frequencies F. feature_dim: global radar feature width.
        encoder_depth, encoder_width: ResNet depth (18/34/50/101/152) and width multiplier.
        coarse_points: size P of the coarse cloud. cloud_dim: width of its PointNet feature.
        local_dim: width of the local radar features; n_offsets: K sampling offsets per query;
            offset_scale: largest offset, in grid_sample units (2 = the whole axis).
        mlp_hidden, mlp_layers: width and hidden layers of the decoder MLP (the others use 2).
        truncation: SDF truncation of the L1 loss (0 = none). w_coarse: weight of the coarse Chamfer.
        lr, weight_decay: Adam settings.
        mesh_resolution, mesh_bound, mesh_batch_points: marching-cubes grid of :meth:`reconstruct`
            over ``[-mesh_bound, mesh_bound]^3`` and queries per decoder call.
    """

    optimizer_class = torch.optim.Adam

    def __init__(
        self,
        num_freq: int = 64,
        feature_dim: int = 256,
        encoder_depth: int = 18,
        encoder_width: float = 1.0,
        coarse_points: int = 1024,
        cloud_dim: int = 128,
        local_dim: int = 64,
        n_offsets: int = 4,
        offset_scale: float = 0.5,
        mlp_hidden: int = 256,
        mlp_layers: int = 4,
        truncation: float = 0.1,
        w_coarse: float = 1.0,
        lr: float = 1e-3,
        weight_decay: float = 0.0,
        mesh_resolution: int = 128,
        mesh_bound: float = 0.55,
        mesh_batch_points: int = 32768,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()
        self.radar = RadarFeatures(num_freq, feature_dim, encoder_depth, encoder_width)
        self.coarse = MLP(feature_dim, mlp_hidden, 2, 3 * coarse_points)
        self.cloud_encoder = MLP(3, cloud_dim, 2, cloud_dim)
        context_dim = 3 + feature_dim + cloud_dim + 4  # q, z, cloud feature, nearest coarse offset + distance
        self.localise = MLP(context_dim, mlp_hidden, 2, 3 * n_offsets)  # (dx, dy, logit) per offset
        self.project = nn.ModuleList(nn.Conv2d(c, local_dim, 1) for c in self.radar.map_channels)
        self.decoder = MLP(context_dim + local_dim, mlp_hidden, mlp_layers, 1)

    # ---- shape context -----------------------------------------------------------------------
    def context(self, radar: torch.Tensor, mask: torch.Tensor) -> ShapeContext:
        maps, z = self.radar(radar, mask)
        coarse = 0.5 * torch.tanh(self.coarse(z)).reshape(z.shape[0], -1, 3)
        cloud = self.cloud_encoder(coarse.detach()).max(dim=1).values
        return ShapeContext([proj(m) for proj, m in zip(self.project, maps)], z, coarse, cloud)

    def query_parts(self, ctx: ShapeContext, queries: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The context split by what varies: per query ``[B, Q, 7]`` (query, nearest coarse offset and
        distance) and per shape ``[B, feature_dim + cloud_dim]`` (global and cloud features)."""
        d2, index = nearest(queries, ctx.coarse.detach())
        near = torch.gather(ctx.coarse.detach(), 1, index[..., None].expand(-1, -1, 3))
        per_query = torch.cat([queries, near - queries, d2.clamp(min=0).sqrt()[..., None]], dim=-1)
        return per_query, torch.cat([ctx.z, ctx.cloud], dim=-1)

    def query_context(self, ctx: ShapeContext, queries: torch.Tensor) -> torch.Tensor:
        """``[B, Q, context_dim]``: the query, global feature, cloud feature and nearest coarse point."""
        d2, index = nearest(queries, ctx.coarse.detach())
        near = torch.gather(ctx.coarse.detach(), 1, index[..., None].expand(-1, -1, 3))
        q = queries.shape[1]
        return torch.cat([
            queries, ctx.z[:, None].expand(-1, q, -1), ctx.cloud[:, None].expand(-1, q, -1),
            near - queries, d2.clamp(min=0).sqrt()[..., None],
        ], dim=-1)

    def local_features(self, ctx: ShapeContext, queries: torch.Tensor, qctx: torch.Tensor) -> torch.Tensor:
        """Attention-weighted features ``[B, Q, local_dim]`` at the predicted radar coordinates, summed over stages."""
        b, q, _ = queries.shape
        k = self.hparams.n_offsets
        offsets = self.localise(qctx).reshape(b, q, k, 3)
        return self._sample_maps(ctx, queries, offsets)

    def _sample_maps(self, ctx: ShapeContext, queries: torch.Tensor, offsets: torch.Tensor) -> torch.Tensor:
        grid = radar_coordinates(queries)[:, :, None] + self.hparams.offset_scale * torch.tanh(offsets[..., :2])
        weights = torch.softmax(offsets[..., 2], dim=-1)  # [B, Q, K]
        if fast_enabled():  # the attention weights are shared by the maps: sum the maps' samples first
            sampled = sum(F.grid_sample(m, grid, mode="bilinear", padding_mode="border", align_corners=False)
                          for m in ctx.maps)
            return (sampled * weights[:, None]).sum(-1).transpose(1, 2)
        local = 0
        for feature_map in ctx.maps:
            sampled = F.grid_sample(feature_map, grid, mode="bilinear", padding_mode="border", align_corners=False)
            local = local + (sampled * weights[:, None]).sum(-1)  # [B, C, Q]
        return local.transpose(1, 2)

    def sdf(self, ctx: ShapeContext, queries: torch.Tensor) -> torch.Tensor:
        """Signed distance ``[B, Q]`` (negative inside) at ``queries [B, Q, 3]``."""
        if fast_enabled():
            per_query, per_shape = self.query_parts(ctx, queries)
            b, q, _ = queries.shape
            offsets = split_mlp(self.localise, per_query, per_shape, 3).reshape(b, q, self.hparams.n_offsets, 3)
            local = self._sample_maps(ctx, queries, offsets)
            return split_mlp(self.decoder, torch.cat([per_query, local], dim=-1), per_shape, 3).squeeze(-1)
        qctx = self.query_context(ctx, queries)
        return self.decoder(torch.cat([qctx, self.local_features(ctx, queries, qctx)], dim=-1)).squeeze(-1)

    # ---- training ----------------------------------------------------------------------------
    def losses(self, batch: dict) -> dict[str, torch.Tensor]:
        ctx = self.context(batch["radar"], batch["radar_mask"])
        sdf_l1 = truncated_l1(self.sdf(ctx, batch["sdf_points"]), batch["sdf_values"], self.hparams.truncation)
        coarse = chamfer_l2(ctx.coarse, batch["surface_points"]).mean()
        return {"loss": sdf_l1 + self.hparams.w_coarse * coarse, "sdf_l1": sdf_l1, "coarse_chamfer": coarse}

    # ---- reconstruction ----------------------------------------------------------------------
    @torch.no_grad()
    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        """Marching cubes of each shape's predicted SDF."""
        from radar2shape.geometry.marching_cubes import extract_mesh

        hp = self.hparams
        ctx = self.context(batch["radar"].to(self.device), batch["radar_mask"].to(self.device))
        recons = []
        for i in range(ctx.z.shape[0]):
            one = ctx.select(i)

            def sdf_fn(points: torch.Tensor, one=one) -> torch.Tensor:
                return self.sdf(one, points.to(self.device, torch.float32)[None])[0]

            mesh = extract_mesh(sdf_fn, hp.mesh_resolution, (-hp.mesh_bound, hp.mesh_bound), hp.mesh_batch_points,
                                self.device, distance_limit=hp.truncation or None)
            recons.append(Reconstruction(mesh=mesh))
        return recons
