"""TMNet baseline (Pan et al. 2019, "Deep Mesh Reconstruction from Single RGB Images via Topology
Modification Networks"), conditioned on radar instead of an image.

Pipeline per shape, with the global radar feature ``z`` (:class:`baselines.radar_features.RadarFeatures`):

    template icosphere v0 --MLP([v0, z])--> v1 = v0 + d1            (deformation stage 1)
    faces of v1 --MLP([centroid, z])--> estimated face error e      (error estimator)
    keep = e <= prune_threshold (never fewer than min_keep of the faces)   (topology modification)
    v1 --MLP([v1, z])--> v2 = v1 + d2 ; mesh = (v2, kept faces)     (deformation stage 2)

Losses: Chamfer between surface samples of each stage (stage 2: kept faces only) and the batch's
ground-truth surface points; edge-length regularisation; a normal loss (edges orthogonal to the
ground-truth normal at each vertex's nearest ground-truth point, Pixel2Mesh's form); and the
error estimator's MSE against the measured distance of each stage-1 face (mean over its corners)
to the ground truth.
All stages train jointly from the first step (TMNet trains them in turn; with ``min_keep`` the
pruning is safe while the estimator is still poor, and a joint schedule is one run in the grid).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from baselines.point_losses import chamfer_l2, nearest
from baselines.radar_features import RadarFeatures
from baselines.template_mesh import icosphere, sample_faces, to_trimesh, unique_edges
from radar2shape.models.base import Reconstruction, ReconstructionModel
from radar2shape.nn.mlp import MLP


class TMNet(ReconstructionModel):
    """Template-sphere deformation with face pruning between two deformation stages.

    Args (primitive, so checkpoints load with ``torch.load(weights_only=True)``):
        num_freq: radar frequencies F. feature_dim: global radar feature width.
        encoder_depth, encoder_width: ResNet depth (18/34/50/101/152) and width multiplier.
        sphere_level, sphere_radius: icosphere subdivisions (4: 2,562 vertices) and radius.
        mlp_hidden, mlp_layers: width and hidden layers of the deformation / error MLPs.
        prune_threshold: faces whose estimated error (mean distance to the ground truth,
            unit-cube units) exceeds it are removed. min_keep: fraction of faces always kept.
        chamfer_samples: surface samples per stage for the Chamfer loss.
        w_edge, w_normal, w_error: loss weights (Chamfer has weight 1).
        lr, weight_decay: Adam settings.
    """

    optimizer_class = torch.optim.Adam

    def __init__(
        self,
        num_freq: int = 64,
        feature_dim: int = 256,
        encoder_depth: int = 18,
        encoder_width: float = 1.0,
        sphere_level: int = 4,
        sphere_radius: float = 0.3,
        mlp_hidden: int = 256,
        mlp_layers: int = 3,
        prune_threshold: float = 0.03,
        min_keep: float = 0.5,
        chamfer_samples: int = 2048,
        w_edge: float = 0.05,
        w_normal: float = 1e-3,
        w_error: float = 1.0,
        lr: float = 1e-3,
        weight_decay: float = 0.0,
    ) -> None:
        super().__init__()
        self.save_hyperparameters()
        self.radar = RadarFeatures(num_freq, feature_dim, encoder_depth, encoder_width)
        vertices, faces = icosphere(sphere_level, sphere_radius)
        self.register_buffer("template", vertices, persistent=False)
        self.register_buffer("faces", faces, persistent=False)
        self.register_buffer("edges", unique_edges(faces), persistent=False)
        self.deform1 = MLP(3 + feature_dim, mlp_hidden, mlp_layers, 3)
        self.deform2 = MLP(3 + feature_dim, mlp_hidden, mlp_layers, 3)
        self.error = MLP(3 + feature_dim, mlp_hidden, mlp_layers, 1)
        for head in (self.deform1, self.deform2):  # start from the template: zero offsets
            nn.init.zeros_(head.net[-1].weight)
            nn.init.zeros_(head.net[-1].bias)

    @staticmethod
    def _with_feature(points: torch.Tensor, feature: torch.Tensor) -> torch.Tensor:
        return torch.cat([points, feature[:, None].expand(-1, points.shape[1], -1)], dim=-1)

    def prune(self, error: torch.Tensor) -> torch.Tensor:
        """Kept faces ``[B, F]`` (bool): estimated error within the threshold, or among the best ``min_keep``."""
        n_keep = math.ceil(self.hparams.min_keep * error.shape[1])
        rank = error.argsort(dim=1).argsort(dim=1)
        return (error <= self.hparams.prune_threshold) | (rank < n_keep)

    def forward(self, radar: torch.Tensor, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        """Both stages' vertices ``[B, V, 3]``, estimated face errors ``[B, F]`` and kept faces ``[B, F]``."""
        _, z = self.radar(radar, mask)
        v0 = self.template.expand(z.shape[0], -1, -1)
        v1 = v0 + self.deform1(self._with_feature(v0, z))
        centroids = v1.detach()[:, self.faces].mean(dim=2)
        error = nn.functional.softplus(self.error(self._with_feature(centroids, z)).squeeze(-1))
        v2 = v1 + self.deform2(self._with_feature(v1, z))
        return {"v1": v1, "v2": v2, "error": error, "keep": self.prune(error.detach())}

    # ---- losses ------------------------------------------------------------------------------
    def face_distance(self, vertex_d2: torch.Tensor) -> torch.Tensor:
        """Measured error of each face ``[B, F]``: mean distance of its corners to the ground truth."""
        return vertex_d2.sqrt()[:, self.faces].mean(-1)

    def edge_loss(self, vertices: torch.Tensor) -> torch.Tensor:
        """Mean squared edge length: keeps the deformed template evenly spread."""
        return (vertices[:, self.edges[:, 0]] - vertices[:, self.edges[:, 1]]).square().sum(-1).mean()

    def normal_loss(self, vertices: torch.Tensor, nearest_gt: torch.Tensor, gt_normals: torch.Tensor) -> torch.Tensor:
        """Mean squared cosine between each edge and the ground-truth normals at its endpoints' nearest points."""
        normals = torch.gather(gt_normals, 1, nearest_gt[..., None].expand(-1, -1, 3))  # [B, V, 3]
        a, b = self.edges[:, 0], self.edges[:, 1]
        direction = nn.functional.normalize(vertices[:, b] - vertices[:, a], dim=-1)
        return ((direction * normals[:, a]).sum(-1).square() + (direction * normals[:, b]).sum(-1).square()).mean() / 2

    def losses(self, batch: dict) -> dict[str, torch.Tensor]:
        out = self(batch["radar"], batch["radar_mask"])
        gt, gt_normals = batch["surface_points"], batch["surface_normals"]
        hp = self.hparams
        d2_1, near_1 = nearest(out["v1"].detach(), gt)
        near_2 = nearest(out["v2"].detach(), gt)[1]
        chamfer1 = chamfer_l2(sample_faces(out["v1"], self.faces, hp.chamfer_samples), gt).mean()
        chamfer2 = chamfer_l2(sample_faces(out["v2"], self.faces, hp.chamfer_samples, out["keep"].float()), gt).mean()
        edge = self.edge_loss(out["v1"]) + self.edge_loss(out["v2"])
        normal = self.normal_loss(out["v1"], near_1, gt_normals) + self.normal_loss(out["v2"], near_2, gt_normals)
        error = (out["error"] - self.face_distance(d2_1)).square().mean()
        loss = chamfer1 + chamfer2 + hp.w_edge * edge + hp.w_normal * normal + hp.w_error * error
        return {
            "loss": loss, "chamfer1": chamfer1, "chamfer2": chamfer2, "edge": edge, "normal": normal,
            "error": error, "kept": out["keep"].float().mean(),
        }

    # ---- reconstruction ----------------------------------------------------------------------
    @torch.no_grad()
    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        """The stage-2 mesh of each shape with its pruned faces removed."""
        out = self(batch["radar"].to(self.device), batch["radar_mask"].to(self.device))
        return [Reconstruction(mesh=to_trimesh(v, self.faces[keep])) for v, keep in zip(out["v2"], out["keep"])]
