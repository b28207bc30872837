"""Stage 1 of Radar2Shape: the hierarchical multiresolution SDF-VAE as a Lightning module.

Surface points are encoded into ``L`` separate latents ``h_l in R^Z`` (one per plane resolution),
decoded into one triplane per level and read by an SDF MLP; see
:mod:`radar2shape.nn.triplane_vae` for the shapes and docs/sdf_vae.md for the choices.

Loss = truncated L1 on SDF samples + ``kl_weight`` * KL(q(h) || N(0, s^2)) averaged over the
L x Z latent elements, ``s = prior_std = 0.25`` a *standard deviation*, as in Diffusion-SDF's code (``Normal(0, kl_std)``
with ``kl_std = 0.25``); the paper writes N(0, 0.25), which read as a variance would be s = 0.5.
We follow the code the method is built on. No plane reconstruction loss.
"""

from __future__ import annotations

from pathlib import Path

import torch
import trimesh
from torch import nn

from radar2shape.checkpoints import load_checkpoint
from radar2shape.errors import UserInputError
from radar2shape.models.base import Reconstruction, ReconstructionModel
from radar2shape.nn.gaussian import gaussian_kl, reparameterize
from radar2shape.nn.triplane_vae import MultiresTriplaneDecoder, MultiresTriplaneEncoder, TriplaneVAESizes


def truncated_l1(pred: torch.Tensor, target: torch.Tensor, truncation: float | None) -> torch.Tensor:
    """Mean L1 between SDFs, both truncated to ``[-t, t]`` (``None``/``<= 0``: plain L1).

    Truncation spends the capacity near the surface, where the mesh is. The prediction is only
    clamped on the side of the target, so a far-off sample with the wrong sign still has a
    gradient (plain DeepSDF clamping of both sides has none there).
    """
    if truncation is None or truncation <= 0:
        return (pred - target).abs().mean()
    far_out, far_in = target >= truncation, target <= -truncation
    pred = torch.where(far_out, pred.clamp(max=truncation), torch.where(far_in, pred.clamp(min=-truncation), pred))
    return (pred - target.clamp(-truncation, truncation)).abs().mean()


def sign_loss(pred: torch.Tensor, target: torch.Tensor, temperature: float) -> torch.Tensor:
    """Mean binary cross-entropy of inside/outside, the predicted SDF read as the logit ``-pred / T``.

    The L1 loss barely sees a thin part: a wing 0.006 thick decoded as empty costs at most 0.003 per
    point, the same as a small offset anywhere else, yet IoU loses the whole wing. This term charges
    a wrong sign about ``log 2`` however close to the surface it is, so it weighs what IoU measures.
    """
    inside = (target < 0).to(pred.dtype)
    return torch.nn.functional.binary_cross_entropy_with_logits(-pred / temperature, inside)


def coarse_level_mask(batch_size: int, n_levels: int, p: float, generator: torch.Generator | None = None) -> torch.Tensor:
    """``[B, L]`` 0/1 mask: with probability ``p`` a sample keeps only its ``k`` coarsest levels,
    ``k`` uniform in ``1 .. L-1``; otherwise all levels.

    Nested ("coarse-to-fine") level dropout: a coarse prefix of the latent must describe the
    whole shape on its own, so level 0 holds the outline and finer levels add detail. Without it
    the levels are interchangeable under the decoder's sum and the KL switches all but one off.
    """
    keep = torch.full((batch_size,), n_levels)
    if n_levels > 1 and p > 0:
        drop = torch.rand(batch_size, generator=generator) < p
        keep = torch.where(drop, torch.randint(1, n_levels, (batch_size,), generator=generator), keep)
    return (torch.arange(n_levels)[None, :] < keep[:, None]).float()


def check_points(batch: dict, key: str) -> torch.Tensor:
    """``batch[key]`` as a non-empty, finite ``[B, N, 3]`` tensor, else a UserInputError naming it."""
    if key not in batch:
        raise UserInputError(f"batch has no '{key}' (keys: {sorted(batch)}); the SDF-VAE needs float [B, N, 3] points")
    points = batch[key]
    shape = tuple(points.shape)
    if points.dim() != 3 or shape[-1] != 3 or shape[0] == 0 or shape[1] == 0:
        raise UserInputError(f"batch['{key}'] must be a non-empty float tensor [B, N>0, 3], got shape {shape}")
    if not torch.isfinite(points).all():
        raise UserInputError(f"batch['{key}'] (shape {shape}) contains NaN or inf values")
    return points


def stage1_weights(path: str | Path, label: str = "stage1_ckpt") -> tuple[dict, dict[str, torch.Tensor]]:
    """``(hyperparameters, state dict)`` of the SDFVAE in a Stage-1 or a Radar2Shape (Stage-2) checkpoint.

    A Stage-2 checkpoint carries its Stage 1 under ``stage1.`` with ``stage1_hparams``, so either
    kind names a Stage 1.
    """
    checkpoint = load_checkpoint(path, "a checkpoint of SDFVAE or RadarDiffusion", label=label)
    hparams = checkpoint.get("hyper_parameters", {})
    if "stage1_hparams" in hparams:
        state = {k.removeprefix("stage1."): v for k, v in checkpoint["state_dict"].items() if k.startswith("stage1.")}
        return dict(hparams["stage1_hparams"]), state
    return dict(hparams), checkpoint["state_dict"]


def matching_weights(state: dict[str, torch.Tensor], model: nn.Module, path: str | Path) -> dict[str, torch.Tensor]:
    """``state`` restricted to ``model``'s weights, or one error line naming the first that differs."""
    own = model.state_dict()
    for name, tensor in own.items():
        if name not in state:
            raise UserInputError(f"init_weights: {path} has no weight {name}: not a Stage 1 of this model's kind")
        if state[name].shape != tensor.shape:
            raise UserInputError(f"init_weights: {path}: {name} is {tuple(state[name].shape)}, this model's is "
                                 f"{tuple(tensor.shape)} (its sizes differ: resolutions, widths, latent_dim)")
    return {name: state[name] for name in own}


class SDFVAE(ReconstructionModel):
    """Hierarchical multiresolution triplane SDF-VAE (Radar2Shape Stage 1).

    Args (all primitive so checkpoints load with ``torch.load(weights_only=True)``):
        resolutions: plane resolution per level (paper: 8, 16, 32, 64); also the hash lattice sizes.
        hash_features, log2_hashmap_size, hash_init_scale: hash encoding F, T and table init range.
        width: point-feature width H; n_blocks: ResNet point blocks per level.
        plane_channels: feature channels C of every plane (encoder and decoder).
        unet_channels, unet_max_depth: first-level width and depth cap of each level's U-Net.
        latent_dim: Z, the size of each level's latent h_l.
        vae_hidden: channels of the posterior/plane-decoder convolutions.
        mlp_hidden, mlp_layers: SDF MLP width and number of hidden layers.
        bound: half-extent of the encoded cube (>0.5 leaves a margin round the unit cube).
        prior_std: standard deviation of the Gaussian prior of every h_l.
        kl_weight: weight of the KL per latent element (mean over the L x Z elements and the
            batch, as Diffusion-SDF); the logged ``kl`` and ``kl/level_i`` are sums in nats.
        kl_warmup_steps: the KL weight ramps linearly from 0 over this many optimizer steps
            (0: none), so no level is switched off before the decoder has learnt to read it.
        init_logvar: initial posterior log-variance (bias of the log-variance head).
        truncation: SDF truncation distance of the L1 loss (unit-cube units; 0 = none).
        sign_weight, sign_temperature: weight of :func:`sign_loss` added to the L1 loss (0: the
            paper's objective) and its temperature T (unit-cube units).
        level_dropout: probability that a training sample is decoded from its coarsest levels
            only (:func:`coarse_level_mask`; 0 = the paper's plain objective).
        lr, weight_decay: Adam settings. lr_decay_steps/lr_decay: step decay (0 steps: constant).
        ema_decay: weight averaging while fitting (0: off; the base model's): validation, tests
            and checkpoints use the average, which steadies a decoder whose IoU swings between checks.
        mesh_resolution: marching-cubes grid size of :meth:`reconstruct`; mesh_batch_points:
            queries per decoder call while extracting meshes.
        surface_level: the decoded SDF value meshed as the surface (0: the zero level set the loss
            trains); only meshing reads it, so it can be chosen for a trained model on the validation
            split (docs/radar_diffusion.md: 0 scores best for both shipped models).
        init_weights: a checkpoint of an SDFVAE of the same sizes, or of a Radar2Shape model (its
            Stage 1 is taken), whose weights this model starts from, e.g. to carry what a Stage 1
            learned on one family into training on another. Not saved with the hyperparameters, so
            this model's own checkpoints load without it (the run's config records it).
    """

    optimizer_class = torch.optim.Adam
    reads_radar = False  # it encodes surface points: the Stage-1 ceiling, not a radar model

    def __init__(
        self,
        resolutions: list[int] = [8, 16, 32, 64],  # noqa: B006 (primitive default for the CLI)
        hash_features: int = 8,
        log2_hashmap_size: int = 19,
        hash_init_scale: float = 1e-4,
        width: int = 128,
        n_blocks: int = 5,
        plane_channels: int = 32,
        unet_channels: int = 32,
        unet_max_depth: int = 4,
        latent_dim: int = 256,
        vae_hidden: int = 128,
        mlp_hidden: int = 256,
        mlp_layers: int = 4,
        bound: float = 0.55,
        prior_std: float = 0.25,
        kl_weight: float = 1e-5,
        kl_warmup_steps: int = 0,
        init_logvar: float = -6.0,
        truncation: float = 0.1,
        sign_weight: float = 0.0,
        sign_temperature: float = 0.0025,
        level_dropout: float = 0.0,
        lr: float = 1e-3,
        weight_decay: float = 0.0,
        lr_decay_steps: int = 0,
        lr_decay: float = 0.5,
        ema_decay: float = 0.0,
        mesh_resolution: int = 128,
        mesh_batch_points: int = 65536,
        surface_level: float = 0.0,
        init_weights: str | None = None,
    ) -> None:
        super().__init__()
        if sign_weight < 0 or sign_temperature <= 0:
            raise UserInputError(f"SDFVAE: sign_weight must be >= 0 and sign_temperature > 0, got {sign_weight} and {sign_temperature}")
        self.save_hyperparameters(ignore=["init_weights"])
        sizes = TriplaneVAESizes.from_dict(self.hparams)
        self.encoder = MultiresTriplaneEncoder(sizes)
        self.decoder = MultiresTriplaneDecoder(sizes)
        if init_weights:
            _, state = stage1_weights(init_weights, label="init_weights")
            self.load_state_dict(matching_weights(state, self, init_weights))

    @property
    def n_levels(self) -> int:
        return len(self.hparams.resolutions)

    # ---- the model's interface -------------------------------------------------------------
    def encode(self, points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Surface points ``[B, N, 3]`` -> posterior ``(mu, logvar)``, each ``[B, L, Z]``."""
        return self.encoder(check_points({"points": points}, "points"))

    def decode_sdf(self, h: torch.Tensor, queries: torch.Tensor) -> torch.Tensor:
        """Latents ``[B, L, Z]`` and query points ``[B, Q, 3]`` -> SDF ``[B, Q]`` (negative inside)."""
        return self.decoder(h, queries)

    def surface_sdf(self, planes: list[torch.Tensor], queries: torch.Tensor) -> torch.Tensor:
        """Decoded SDF ``[B, Q]`` shifted so that its zero level is the meshed surface (``surface_level``).

        Everything that meshes or labels occupancy reads this, never the raw decoder, so the level
        set chosen for a model is the one its meshes, IoU and uncertainty all see.
        """
        return self.decoder.query(planes, queries) - float(self.hparams.surface_level)

    @torch.no_grad()
    def extract_mesh(self, h: torch.Tensor, resolution: int | None = None) -> list[trimesh.Trimesh]:
        """One marching-cubes mesh per latent of ``h [B, L, Z]`` over ``[-bound, bound]^3``."""
        from radar2shape.geometry.marching_cubes import extract_mesh

        resolution = int(resolution or self.hparams.mesh_resolution)
        bound = self.hparams.bound
        meshes = []
        for planes in zip(*self.decoder.decode_planes(h)):
            planes = [p[None] for p in planes]

            def sdf_fn(points: torch.Tensor, planes=planes) -> torch.Tensor:
                return self.surface_sdf(planes, points[None].to(planes[0].dtype))[0]

            meshes.append(extract_mesh(sdf_fn, resolution, (-bound, bound), self.hparams.mesh_batch_points, self.device,
                                       distance_limit=self.hparams.truncation or None))
        return meshes

    @torch.no_grad()
    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        """Encode ``batch['surface_points']``, decode the posterior mean, mesh it."""
        mu, _ = self.encoder(check_points(batch, "surface_points"))
        return [Reconstruction(mesh=m) for m in self.extract_mesh(mu)]

    # ---- training ----------------------------------------------------------------------------
    def losses(self, batch: dict, sample: bool = True) -> dict[str, torch.Tensor]:
        """Loss terms of one batch; ``sample=False`` (evaluation) decodes the posterior mean, all levels."""
        mu, logvar = self.encoder(check_points(batch, "surface_points"))
        queries = check_points(batch, "sdf_points")
        h = reparameterize(mu, logvar) if sample else mu
        mask = None
        if sample and self.hparams.level_dropout > 0:
            mask = coarse_level_mask(mu.shape[0], self.n_levels, self.hparams.level_dropout).to(mu)
        sdf = self.decoder(h, queries, mask)
        sdf_l1 = truncated_l1(sdf, batch["sdf_values"], self.hparams.truncation)
        kl_elements = gaussian_kl(mu, logvar, self.hparams.prior_std)  # [B, L, Z]
        kl_levels = kl_elements.sum(-1).mean(0)  # [L], nats per level (logged)
        # The loss weighs the KL per latent element (mean over L x Z), as Diffusion-SDF does.
        out = {"loss": sdf_l1 + self.kl_weight() * kl_elements.mean(), "sdf_l1": sdf_l1, "kl": kl_levels.sum()}
        if self.hparams.sign_weight > 0:
            out["sign"] = sign_loss(sdf, batch["sdf_values"], self.hparams.sign_temperature)
            out["loss"] = out["loss"] + self.hparams.sign_weight * out["sign"]
        out.update({f"kl/level_{l}": kl_levels[l] for l in range(self.n_levels)})
        return out

    def eval_losses(self, batch: dict, batch_idx: int) -> dict[str, torch.Tensor]:
        """Deterministic validation/test losses: the posterior mean, all levels."""
        return self.losses(batch, sample=False)

    def kl_weight(self) -> float:
        """KL weight at the current step (linear warm-up, then ``kl_weight``)."""
        warmup = self.hparams.kl_warmup_steps
        ramp = 1.0 if warmup <= 0 else min(1.0, self.global_step / warmup)
        return self.hparams.kl_weight * ramp

    def predict_step(self, batch: dict, batch_idx: int, dataloader_idx: int = 0) -> dict[str, torch.Tensor]:
        """Posterior of each shape for Stage 2: ``mu``, ``logvar`` ``[B, L, Z]`` and the record ``index``."""
        mu, logvar = self.encoder(check_points(batch, "surface_points"))
        index = batch.get("index", torch.arange(mu.shape[0]) + batch_idx * mu.shape[0])
        return {"mu": mu, "logvar": logvar, "index": index}
