"""Stage 2 of Radar2Shape: radar-conditional coarse-to-fine diffusion over Stage-1 latents.

Token sequence (L = number of Stage-1 levels = number of frequency blocks)::

    r_0, h_0, r_1, h_1, ..., r_{L-1}, h_{L-1}      with a lower-triangular attention mask

so ``h_l`` sees radar blocks ``r_{<=l}`` and coarser shape tokens ``h_{<l}`` (and itself), never
finer ones: the coarse latent is explained by the low-frequency band first. All ``h`` tokens are
noised at one timestep; the loss is the MSE of the predicted noise on the ``h`` tokens.

Latents are the frozen Stage-1 posterior means, standardised per level with statistics taken
from the training set at fit start (buffers, so they travel in the checkpoint). The Stage-1
weights and hyperparameters are copied into this module's checkpoint: a Stage-2 checkpoint alone
reconstructs meshes. See docs/radar_diffusion.md.
"""

from __future__ import annotations

import contextvars
from pathlib import Path

import numpy as np
import torch
import trimesh
from torch import nn
from torch.nn import functional as F

from radar2shape.checkpoints import load_checkpoint
from radar2shape.errors import UserInputError
from radar2shape.models.base import Reconstruction, ReconstructionModel
from radar2shape.models.sdf_vae import SDFVAE, stage1_weights
from radar2shape.nn.diffusion import GaussianDiffusion, drop_condition, guided
from radar2shape.nn.positional import TimestepEmbedding, sinusoidal_embedding
from radar2shape.nn.radar_encoder import PADDINGS, RadarBlockEncoder
from radar2shape.nn.transformer import Transformer, causal_mask
from radar2shape.radar.spec import RadarSpec


def load_stage1(path: str | Path) -> SDFVAE:
    """A Stage-1 :class:`SDFVAE` from a Lightning checkpoint (``weights_only`` load).

    ``path`` may also be a Stage-2 checkpoint (a trained or shipped Radar2Shape model): it carries
    its Stage 1's weights and hyperparameters, so a new Stage 2 can start from that exact Stage 1.
    """
    hparams, state = stage1_weights(path, label="stage1_ckpt")
    try:
        stage1 = SDFVAE(**{k: v for k, v in hparams.items() if not k.startswith("_")})  # not the CLI's _class_path
        stage1.load_state_dict(state)
        return stage1
    except (KeyError, TypeError, ValueError, RuntimeError) as err:
        message = f"stage1_ckpt: {path} is not a checkpoint of SDFVAE or RadarDiffusion ({type(err).__name__}: {err})"
        raise UserInputError(message) from err


def load_latent_cache(path: str | Path) -> dict[int, torch.Tensor]:
    """``{record index: posterior mean [L, Z]}`` from a ``.pt``/``.npz`` with ``mu [N, L, Z]``, ``index [N]``."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"latent_cache: {path} not found")
    data = dict(np.load(path)) if path.suffix == ".npz" else torch.load(path, map_location="cpu", weights_only=True)
    if "mu" not in data or "index" not in data:
        raise UserInputError(f"latent_cache: {path} must hold 'mu' [N, L, Z] and 'index' [N], got {sorted(data)}")
    mu, index = torch.as_tensor(np.asarray(data["mu"]), dtype=torch.float32), np.asarray(data["index"]).astype(int)
    return {int(i): m for i, m in zip(index, mu)}


class LatentStandardiser(nn.Module):
    """Per-level standardisation ``(h - mean_l) / std_l``: a mean per dimension, one std per level.

    One std per level (not per dimension) keeps the relative scale of a level's dimensions, which
    the decoder relies on, while putting every level's noise-to-signal ratio on the same footing.
    """

    def __init__(self, n_levels: int, latent_dim: int) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(n_levels, latent_dim))
        self.register_buffer("std", torch.ones(n_levels, 1))
        self.register_buffer("ready", torch.tensor(False))

    @torch.no_grad()
    def fit(self, latents: torch.Tensor, min_std: float = 1e-4) -> None:
        """Set the statistics from training latents ``[N, L, Z]``."""
        self.mean.copy_(latents.mean(0))
        self.std.copy_((latents - self.mean).flatten(2).std(dim=(0, 2)).clamp(min=min_std)[:, None])
        self.ready.fill_(True)

    def forward(self, h: torch.Tensor) -> torch.Tensor:
        return (h - self.mean) / self.std

    def inverse(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.std + self.mean


def copy_radar_encoder(source: dict, encoder: nn.Module, path: str) -> None:
    """Copy the ``radar_encoder.*`` weights of a RadarDiffusion state dict into ``encoder``.

    A source read with zero roll padding lacks the two roll-angle input channels of circular
    padding (the stem's last two); they start at zero, so the copy computes what the source's
    encoder did, up to the padding at the roll edge. Any other difference is one clear error.
    """
    prefix = "radar_encoder."
    weights = {key[len(prefix):]: value for key, value in source.items() if key.startswith(prefix)}
    target = encoder.state_dict()
    if set(weights) != set(target):
        raise UserInputError(f"init_encoder: {path}: its radar encoder has other layers than this model's "
                             "(encoder_depth, roll_padding?)")
    for name, value in weights.items():
        want = target[name]
        if value.shape != want.shape and value.dim() == 4:  # a stem [out, in, k, k] lacking the roll-angle inputs
            value = torch.cat([value, value.new_zeros(value.shape[0], encoder.roll_channels, *value.shape[2:])], dim=1)
        if value.shape != want.shape:
            raise UserInputError(f"init_encoder: {path}: radar_encoder.{name} is {tuple(weights[name].shape)}, this "
                                 f"model's {tuple(want.shape)} (encoder_width, num_freq or levels differ)")
        target[name] = value
    encoder.load_state_dict(target)


class RadarDiffusion(ReconstructionModel):
    """Radar -> Stage-1 latents by causal Transformer diffusion; meshes through the frozen Stage-1 decoder.

    Args (primitive, so checkpoints load with ``torch.load(weights_only=True)``):
        stage1_ckpt: Stage-1 SDFVAE checkpoint, or a Stage-2 checkpoint whose Stage 1 is taken (read
            once; its weights are copied into this model).
        stage1_hparams: filled in from ``stage1_ckpt``; lets a Stage-2 checkpoint rebuild Stage 1 alone.
        latent_cache: optional ``.pt``/``.npz`` of training latents (``mu``, ``index``), instead of
            encoding ``surface_points`` with Stage 1 at fit start.
        init_weights: a RadarDiffusion checkpoint of the same architecture whose weights (Stage 2,
            its Stage 1 and latent statistics) this model starts from, e.g. to fine-tune a model
            trained on fully observed radar to masked radar. Read only when the model is built
            fresh, like ``stage1_ckpt``: a checkpoint of the fine-tuned model loads without it.
        init_encoder: a RadarDiffusion checkpoint whose radar encoder alone this model starts from
            (:func:`copy_radar_encoder`), e.g. one trained on another family on the same radar
            grid: the encoder reads physics every family shares, while the denoiser's latents
            belong to its own Stage 1. Read only when the model is built fresh.
        cache_turned_latents: with the DataModule's ``roll_augment``, keep each (record, turn)'s
            latents the first time they are encoded and reuse them, as the cache above does for the
            unturned pose (one record has 2 R poses, so Stage 1 stops running once most were seen).
        canonical_heading: learn every shape in its canonical heading: with ``roll_augment`` the
            target of a turned radar is its record's unturned latent, so the network reads the shape
            and not the heading (which the axis-aligned Stage-1 planes draw poorly when turned,
            docs/radar_diffusion.md); :meth:`reconstruct` then finds the heading from the radar
            (:meth:`place_in_heading`) and turns the mesh into it. refine_heading: place it between
            roll steps where the neighbouring turns say so (else at the nearest whole step).
        canonical_classes: ``canonical_heading`` for these classes only (names of the data's classes;
            those whose files share a front, such as aircraft): their turned samples target the
            unturned latent, every other class its turned one (with ``cache_turned_latents`` if set),
            and :meth:`reconstruct` searches the heading of every reconstruction. For a Stage 1 that
            draws those classes in their stored heading only (the DataModule's
            ``roll_augment_skip_classes``) and the others turned.
        num_freq: number of radar frequencies F, cut into L contiguous blocks (equal when L divides F).
        dim, n_layers, n_heads, mlp_ratio, dropout: Transformer width D, depth, heads, MLP ratio.
        encoder_depth, encoder_width: ResNet depth (18/34/50/101/152) and width multiplier.
        roll_padding: "zeros" or "circular": how the radar ResNet pads the roll axis
            (:class:`~radar2shape.nn.radar_encoder.RadarBlockEncoder`; circular adds roll-angle channels).
        encoder_stem_stride: stride of the radar ResNet's stem (1 or 2; 2 quarters the work of its
            first stage, docs/throughput.md).
        num_steps, schedule: diffusion steps T and noise schedule (``cosine`` or ``linear``).
        eps_skip: predict the noise as ``sqrt(1 - abar) h_t + sqrt(abar) net`` (see
            :meth:`GaussianDiffusion.skip_eps`; without it, samples from the cosine schedule explode).
        loss: ``v`` (MSE on the network's velocity output; needs ``eps_skip``) or ``eps`` (MSE on
            the predicted noise, which gives the high-noise steps almost no weight: on parts_tiny
            it left the radar conditioning weak, docs/radar_diffusion.md).
        clip_x0: clamp of the predicted (standardised) latent while sampling; 0 = off.
        num_samples, sample_steps, sample_eta, sampler: defaults of :meth:`reconstruct` (K samples,
            ``ddim`` with that many steps and eta, or ``ddpm``).
        mesh_resolution: marching-cubes grid of :meth:`reconstruct`; sample_seed: sampling seed.
        lr, weight_decay: AdamW settings; lr_decay_steps / lr_decay: the rate times ``lr_decay`` every
            that many steps (0: constant). ema_decay: exponential moving average of the weights used
            for validation, checkpoints and sampling (0 = off; the last iterate is noisy at a constant rate).
        cond_drop, guidance: classifier-free guidance: that share of training samples sees the
            "nothing observed" radar (zero, fully masked), and sampling uses
            ``eps_u + guidance (eps_c - eps_u)`` (1 = plain conditional sampling, no extra cost).

    The radar grid and dB normalisation come from the DataModule at fit start
    (:attr:`radar_spec`, stored in the checkpoint); :meth:`check_radar_spec` refuses data whose
    frequency count differs from ``num_freq``.
    """

    def __init__(
        self,
        stage1_ckpt: str | None = None,
        stage1_hparams: dict | None = None,
        latent_cache: str | None = None,
        cache_turned_latents: bool = False,
        canonical_heading: bool = False,
        refine_heading: bool = True,
        canonical_classes: list[str] | None = None,
        init_weights: str | None = None,
        init_encoder: str | None = None,
        num_freq: int = 64,
        dim: int = 512,
        n_layers: int = 8,
        n_heads: int = 8,
        mlp_ratio: float = 4.0,
        dropout: float = 0.0,
        encoder_depth: int = 152,
        encoder_width: float = 1.0,
        roll_padding: str = "zeros",
        encoder_stem_stride: int = 1,
        num_steps: int = 1000,
        schedule: str = "cosine",
        eps_skip: bool = True,
        loss: str = "v",
        clip_x0: float = 0.0,
        num_samples: int = 1,
        sample_steps: int = 50,
        sample_eta: float = 0.0,
        sampler: str = "ddim",
        mesh_resolution: int = 128,
        sample_seed: int = 0,
        lr: float = 1e-4,
        weight_decay: float = 0.0,
        lr_decay_steps: int = 0,
        lr_decay: float = 0.5,
        cond_drop: float = 0.0,
        guidance: float = 1.0,
        ema_decay: float = 0.0,
    ) -> None:
        super().__init__()
        if roll_padding not in PADDINGS:
            raise UserInputError(f"RadarDiffusion: roll_padding must be one of {', '.join(PADDINGS)}, got {roll_padding!r}")
        if encoder_stem_stride not in (1, 2):
            raise UserInputError(f"RadarDiffusion: encoder_stem_stride must be 1 or 2, got {encoder_stem_stride}")
        if loss not in ("v", "eps"):
            raise UserInputError(f"RadarDiffusion: loss must be 'v' or 'eps', got {loss!r}")
        if canonical_heading and cache_turned_latents:
            raise UserInputError("RadarDiffusion: canonical_heading learns unturned latents; cache_turned_latents "
                                 "(turned ones) contradicts it: set one of them")
        if canonical_classes and canonical_heading:
            raise UserInputError("RadarDiffusion: canonical_heading learns every class in its canonical heading; "
                                 "canonical_classes names the classes that are: set one of them")
        if init_weights and init_encoder:
            raise UserInputError("RadarDiffusion: init_weights starts every weight from a checkpoint, init_encoder "
                                 "only the radar encoder: set one of them")
        if loss == "v" and not eps_skip:
            raise UserInputError("RadarDiffusion: loss='v' needs eps_skip=true (the network output is the velocity)")
        # A fresh contextvars.Context: the Lightning CLI hands its hyperparameters (a ContextVar) to
        # every LightningModule built while it instantiates the model, which would give Stage 1
        # this model's hyperparameters instead of its own.
        fresh = stage1_hparams is None
        if fresh:
            if stage1_ckpt is None:
                raise UserInputError("RadarDiffusion needs stage1_ckpt (a trained Stage-1 SDFVAE checkpoint)")
            stage1 = contextvars.Context().run(load_stage1, stage1_ckpt)
            stage1_hparams = dict(stage1.hparams)
        else:  # weights arrive with this model's state dict
            stage1 = contextvars.Context().run(SDFVAE, **stage1_hparams)
        self.save_hyperparameters()
        self.hparams.stage1_hparams = dict(stage1_hparams)
        self.stage1 = stage1.eval().requires_grad_(False)
        self.n_levels, self.latent_dim = stage1.n_levels, int(stage1.hparams.latent_dim)

        self.standardiser = LatentStandardiser(self.n_levels, self.latent_dim)
        self.radar_encoder = RadarBlockEncoder(num_freq, self.n_levels, dim, encoder_depth, encoder_width,
                                               roll_padding, encoder_stem_stride)
        self.latent_in = nn.Linear(self.latent_dim, dim)
        self.token_type = nn.Parameter(torch.zeros(2, dim))  # 0: radar token, 1: shape token
        self.time_embed = TimestepEmbedding(dim)
        self.transformer = Transformer(dim, n_layers, n_heads, mlp_ratio, dropout, cond_dim=dim)
        self.latent_out = nn.Linear(dim, self.latent_dim)
        nn.init.zeros_(self.latent_out.weight)
        nn.init.zeros_(self.latent_out.bias)
        self.diffusion = GaussianDiffusion(num_steps, schedule, clip_x0 or None)
        self.register_buffer("attn_mask", causal_mask(2 * self.n_levels), persistent=False)
        self._train_latents: dict[int, torch.Tensor] = {}
        self._turned_latents: dict[tuple[int, int], torch.Tensor] = {}  # (record, roll_turn) -> latents
        self._canonical_labels: frozenset[int] = frozenset()  # canonical_classes' labels in the training data
        if fresh and init_weights:
            self.load_state_dict(load_checkpoint(init_weights, "a RadarDiffusion checkpoint", label="init_weights")["state_dict"])
        if fresh and init_encoder:
            source = load_checkpoint(init_encoder, "a RadarDiffusion checkpoint", label="init_encoder")["state_dict"]
            copy_radar_encoder(source, self.radar_encoder, init_encoder)

    def train(self, mode: bool = True):
        """Stage 1 stays in eval mode: it is frozen."""
        super().train(mode)
        self.stage1.eval()
        return self

    # ---- the denoiser ------------------------------------------------------------------------
    def encode_radar(self, radar: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Radar ``[B, A, R, F]`` + mask ``[B, A, R]`` -> radar tokens ``[B, L, D]`` (once per sampling run)."""
        if radar.dim() != 4 or radar.shape[-1] != self.hparams.num_freq:
            raise UserInputError(f"radar must be [B, A, R, F={self.hparams.num_freq}], got {tuple(radar.shape)}")
        return self.radar_encoder(radar, mask) + self.token_type[0]

    def network_output(self, radar_tokens: torch.Tensor, h_t: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """The Transformer's output ``[B, L, Z]`` at the shape tokens (the velocity when ``eps_skip``)."""
        levels = sinusoidal_embedding(torch.arange(self.n_levels, device=h_t.device), self.hparams.dim)
        shape_tokens = self.latent_in(h_t) + levels + self.token_type[1]
        tokens = torch.stack([radar_tokens, shape_tokens], dim=2).flatten(1, 2)  # r_0, h_0, r_1, h_1, ...
        return self.latent_out(self.transformer(tokens, self.time_embed(t), self.attn_mask)[:, 1::2])

    def denoise_tokens(self, radar_tokens: torch.Tensor, h_t: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """Predicted noise ``[B, L, Z]`` of standardised noisy latents ``h_t`` at timesteps ``t [B]``."""
        out = self.network_output(radar_tokens, h_t, t)
        return self.diffusion.skip_eps(h_t, t, out) if self.hparams.eps_skip else out

    def forward(self, radar: torch.Tensor, mask: torch.Tensor, h_t: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """Predicted noise ``[B, L, Z]`` from the radar ``[B, A, R, F]``, its mask and noisy latents at ``t``."""
        return self.denoise_tokens(self.encode_radar(radar, mask), h_t, t)

    # ---- latents -----------------------------------------------------------------------------
    @torch.no_grad()
    def encode_shapes(self, batch: dict) -> torch.Tensor:
        """Stage-1 posterior means ``[B, L, Z]``: from the training cache when every index is in it.

        Not for a batch of turned samples (``roll_turn``, the DataModule's ``roll_augment``): the cache
        holds each record's latents in one pose, and pairing them with turned radar would teach the
        model that the radar says nothing about the shape. Those are keyed by their turn instead
        (``cache_turned_latents``).
        """
        index = batch.get("index")
        if self.training and index is not None:
            if "roll_turn" in batch and self.hparams.get("canonical_classes"):
                return self._per_class_latents(batch, index)
            if "roll_turn" in batch and self.hparams.get("canonical_heading", False):
                rows = [self._train_latents.get(int(i)) for i in index]
                if any(r is None for r in rows):
                    raise UserInputError("canonical_heading: a training record has no cached unturned latent "
                                         "(the latent_cache must hold every training record)")
                return torch.stack(rows).to(self.device)
            if "roll_turn" in batch:
                if self.hparams.get("cache_turned_latents", False):
                    return self._cached_turned(batch, index, batch["roll_turn"])
            elif self._train_latents:
                rows = [self._train_latents.get(int(i)) for i in index]
                if all(r is not None for r in rows):
                    return torch.stack(rows).to(self.device)
        return self.stage1.encode(batch["surface_points"])[0]

    def _cached_turned(self, batch: dict, index: torch.Tensor, turn: torch.Tensor) -> torch.Tensor:
        """Latents of turned samples: Stage 1 encodes only the (record, turn) pairs not seen before."""
        keys = list(zip(index.tolist(), turn.tolist()))
        new = [i for i, key in enumerate(keys) if key not in self._turned_latents]
        if new:
            for i, mu in zip(new, self.stage1.encode(batch["surface_points"][new])[0]):
                self._turned_latents[keys[i]] = mu.clone()
        return torch.stack([self._turned_latents[key] for key in keys]).to(self.device)

    def _per_class_latents(self, batch: dict, index: torch.Tensor) -> torch.Tensor:
        """The targets of ``canonical_classes``: unturned latents for those classes, turned ones otherwise
        (Stage 1 encodes only the rows of other classes)."""
        canonical = [int(label) in self._canonical_labels for label in batch["label"].tolist()]
        rows: list[torch.Tensor | None] = [self._train_latents.get(int(i)) if c else None for i, c in zip(index, canonical)]
        if any(c and row is None for c, row in zip(canonical, rows)):
            raise UserInputError("canonical_classes: a training record has no cached unturned latent "
                                 "(they are encoded at fit start from the DataModule)")
        turned = [k for k, c in enumerate(canonical) if not c]
        if turned:
            part = {key: batch[key][turned] for key in ("surface_points", "roll_turn")}
            latents = self._cached_turned(part, index[turned], part["roll_turn"]) \
                if self.hparams.get("cache_turned_latents", False) else self.stage1.encode(part["surface_points"])[0]
            for k, latent in zip(turned, latents):
                rows[k] = latent
        return torch.stack([row.to(self.device) for row in rows])

    @torch.no_grad()
    def collect_train_latents(self, loader) -> dict[int, torch.Tensor]:
        """Posterior means of every training shape, keyed by record index (one pass over ``loader``)."""
        latents = {}
        for batch in loader:
            mu, _ = self.stage1.encode(batch["surface_points"].to(self.device))
            for i, m in zip(batch["index"].tolist(), mu.cpu()):
                latents[int(i)] = m
        return latents

    def check_radar_spec(self, spec: RadarSpec) -> None:
        """The data must be the full ``[A, R, F]`` radar with ``num_freq`` frequencies."""
        num_freq = len(spec.grid.freq_hz)
        if spec.roll_symmetric or num_freq != self.hparams.num_freq:
            raise UserInputError(
                f"{type(self).__name__}: expects [A, R, F={self.hparams.num_freq}] radar, the data's radar spec is "
                f"{spec.describe()}; set num_freq or use a 3D DataModule"
            )

    def on_fit_start(self) -> None:
        """Adopt the DataModule's radar spec; collect training latents and their statistics."""
        super().on_fit_start()
        datamodule = self.trainer.datamodule
        if self.hparams.get("canonical_classes"):
            if not hasattr(datamodule, "labels_of"):
                raise UserInputError("canonical_classes needs a DataModule with named classes")
            self._canonical_labels = frozenset(datamodule.labels_of("canonical_classes", self.hparams.canonical_classes))
        if self.hparams.latent_cache:
            self._train_latents = load_latent_cache(self.hparams.latent_cache)
        elif datamodule is not None:
            canonical = (self.hparams.get("canonical_heading", False) or bool(self.hparams.get("canonical_classes"))) \
                and hasattr(datamodule, "unturned_train_dataloader")
            self._train_latents = self.collect_train_latents(
                datamodule.unturned_train_dataloader() if canonical else datamodule.train_dataloader())
        if not bool(self.standardiser.ready):
            if not self._train_latents:
                raise UserInputError("no training latents to standardise: give a DataModule or latent_cache")
            self.standardiser.fit(torch.stack(list(self._train_latents.values())).to(self.device))

    # ---- training ----------------------------------------------------------------------------
    def diffusion_loss(self, batch: dict, generator: torch.Generator | None = None) -> torch.Tensor:
        """MSE of the velocity (``loss='v'``) or the noise of all shape tokens at one random timestep per shape."""
        x0 = self.standardiser(self.encode_shapes(batch))
        t = self.diffusion.sample_timesteps(x0.shape[0], x0.device, generator)
        noise = torch.randn(x0.shape, generator=generator, device=x0.device)
        radar, mask = batch["radar"], batch["radar_mask"]
        if self.training and generator is None:  # guidance: learn the unconditional model too
            radar, mask = drop_condition(radar, mask, float(self.hparams.get("cond_drop", 0.0)))
        radar_tokens = self.encode_radar(radar, mask)
        h_t = self.diffusion.q_sample(x0, t, noise)
        if self.hparams.get("loss", "eps") == "v":
            return F.mse_loss(self.network_output(radar_tokens, h_t, t), self.diffusion.v_target(x0, t, noise))
        return F.mse_loss(self.denoise_tokens(radar_tokens, h_t, t), noise)

    def losses(self, batch: dict) -> dict[str, torch.Tensor]:
        return {"loss": self.diffusion_loss(batch)}

    def eval_losses(self, batch: dict, batch_idx: int) -> dict[str, torch.Tensor]:
        """The diffusion loss with noise and timesteps seeded by ``batch_idx``: the same every epoch."""
        return {"loss": self.diffusion_loss(batch, torch.Generator(self.device).manual_seed(batch_idx))}

    # ---- sampling and meshes -----------------------------------------------------------------
    @torch.no_grad()
    def sample_latents(
        self,
        batch: dict,
        num_samples: int | None = None,
        steps: int | None = None,
        eta: float | None = None,
        sampler: str | None = None,
        sample_seed: int | None = None,
    ) -> torch.Tensor:
        """``K`` Stage-1 latents per input, ``[B, K, L, Z]`` (de-standardised), by DDIM or DDPM."""
        hp = self.hparams
        k = int(num_samples or hp.num_samples)
        radar, mask = batch["radar"].to(self.device), batch["radar_mask"].to(self.device)
        radar_tokens = self.encode_radar(radar, mask).repeat_interleave(k, dim=0)
        scale = float(hp.get("guidance", 1.0))
        null_tokens = None if scale == 1.0 else \
            self.encode_radar(torch.zeros_like(radar), torch.zeros_like(mask)).repeat_interleave(k, dim=0)
        generator = torch.Generator(self.device).manual_seed(hp.sample_seed if sample_seed is None else sample_seed)
        x = self.diffusion.sample(
            guided(lambda h_t, t: self.denoise_tokens(radar_tokens, h_t, t),
                   lambda h_t, t: self.denoise_tokens(null_tokens, h_t, t), scale),
            (radar_tokens.shape[0], self.n_levels, self.latent_dim),
            method=sampler or hp.sampler,
            steps=steps or hp.sample_steps,
            eta=hp.sample_eta if eta is None else eta,
            generator=generator,
            device=self.device,
        )
        return self.standardiser.inverse(x).reshape(-1, k, self.n_levels, self.latent_dim)

    def sdf_function(self, h: torch.Tensor):
        """``points [N, 3] -> SDF [K, N]`` for latents ``h [K, L, Z]``, planes decoded once.

        The SDF is Stage 1's :meth:`~SDFVAE.surface_sdf`: its zero level is the meshed surface.
        """
        decoder = self.stage1.decoder
        planes = decoder.decode_planes(h)

        def sdf(points: torch.Tensor) -> torch.Tensor:
            q = torch.as_tensor(points, dtype=planes[0].dtype, device=planes[0].device)
            return self.stage1.surface_sdf(planes, q[None].expand(h.shape[0], -1, -1))

        return sdf

    @torch.no_grad()
    def mean_mesh(self, h: torch.Tensor, resolution: int | None = None) -> tuple[trimesh.Trimesh, np.ndarray]:
        """Marching cubes of the mean SDF of latents ``h [K, L, Z]``, and the SDF std over K at its vertices."""
        from radar2shape.geometry.marching_cubes import extract_mesh

        sdf = self.sdf_function(h)
        bound = float(self.stage1.hparams.bound)
        mesh = extract_mesh(
            lambda p: sdf(p).mean(0), int(resolution or self.hparams.mesh_resolution), (-bound, bound),
            int(self.stage1.hparams.mesh_batch_points), self.device,
            distance_limit=self.stage1.hparams.truncation or None,
        )
        if len(mesh.vertices) == 0:
            return mesh, np.zeros(0, dtype=np.float32)
        spread = sdf(torch.as_tensor(mesh.vertices, dtype=torch.float32, device=self.device)).std(0, unbiased=False)
        return mesh, spread.cpu().numpy()

    @torch.no_grad()
    def reconstruct_with_uncertainty(
        self, batch: dict, num_samples: int | None = None, steps: int | None = None, resolution: int | None = None,
        sample_seed: int | None = None,
    ) -> list[tuple[Reconstruction, np.ndarray]]:
        """Per input: the mesh of the mean SDF of K sampled shapes, and the per-vertex SDF std across them.

        The std (unit-cube units) is where the K plausible shapes disagree: a cheap uncertainty map.
        """
        latents = self.sample_latents(batch, num_samples=num_samples, steps=steps, sample_seed=sample_seed)
        out = []
        for i, h in enumerate(latents):
            mesh, spread = self.mean_mesh(h, resolution)
            out.append((Reconstruction(mesh=self.place_in_heading(mesh, batch, i)), spread))
        return out

    def place_in_heading(self, mesh: trimesh.Trimesh, batch: dict, i: int) -> trimesh.Trimesh:
        """``mesh`` turned into the heading that input ``i`` of ``batch`` shows (``canonical_heading``
        models; others return it as it is).

        The canonical mesh is simulated once with PO on the model's radar grid; of the 2R turns by
        whole roll steps and the mirror, which only re-index that response, the one whose dB map
        correlates best with the observed cells wins, its shift refined between steps by the
        neighbouring correlations (:mod:`radar2shape.radar.heading`; ``scripts/heading_from_radar.py``
        measures the search on real objects). With ``canonical_classes`` every mesh is searched, since
        the class is not known at test time (one in its observed heading is found unturned). The
        turned mesh is put back in the normalised frame of the observed heading
        (:func:`radar2shape.geometry.normalise.turned_in_frame`).
        """
        searched = self.hparams.get("canonical_heading", False) or bool(self.hparams.get("canonical_classes"))
        if not searched or len(mesh.faces) == 0:
            return mesh
        from radar2shape.geometry.normalise import scaled, turned_in_frame
        from radar2shape.radar import simulate
        from radar2shape.radar.heading import estimate_turn, refined_shift, turn_rotation

        grid = self.radar_spec.grid
        observed = self.radar_spec.denormalise(batch["radar"][i].detach().cpu().numpy())
        mask = batch["radar_mask"][i].detach().cpu().numpy().astype(bool)
        simulated = self.radar_spec.to_db(simulate(scaled(mesh, grid.size_m), grid.aspect_rad, grid.roll_rad, grid.freq_hz))
        turn, scores = estimate_turn(observed, simulated, grid.roll_rad, mask=mask)
        count = len(grid.roll_rad)
        shift = refined_shift(scores, turn, count) if self.hparams.get("refine_heading", True) else turn[0]
        return turned_in_frame(mesh, turn_rotation(count, shift, turn[1]))

    @torch.no_grad()
    def reconstruct_ceiling(self, batch: dict) -> list[Reconstruction] | None:
        """Stage 1's posterior means of the true shapes, meshed as :meth:`reconstruct` meshes samples.

        A Stage-2 sample is decoded by the same frozen decoder, so this bounds what Stage 2 can
        reach on these shapes; None when the batch has no ``surface_points``.
        """
        if "surface_points" not in batch:
            return None
        mu, _ = self.stage1.encode(batch["surface_points"].to(self.device))
        return [Reconstruction(mesh=self.mean_mesh(h[None])[0]) for h in mu]

    @torch.no_grad()
    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        """Sample ``num_samples`` latents per input (DDIM by default), decode, marching cubes (mean SDF when K > 1)."""
        return [recon for recon, _ in self.reconstruct_with_uncertainty(batch)]
