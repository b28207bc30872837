"""Roll-symmetric reconstruction: the profile U-Net diffusion model, and what all profile models share.

A roll-symmetric shape is its (r, z) profile (``geometry.profile``), so these models predict ``P``
profile points from the aspect x frequency radar ``[A, F]`` and revolve them into a mesh for the
3D metrics. :class:`ProfileModel` holds the parts every profile model needs (batch checks, the
profile normalisation, turning predictions into valid profiles and meshes); the InvRT baseline
(``baselines/invrt.py``) shares it, so both are scored identically.
"""

from __future__ import annotations

import numpy as np
import torch
import trimesh
from torch import nn
from torch.nn import functional as F

from radar2shape.errors import UserInputError
from radar2shape.geometry.profile import profile_to_mesh, validate_profile
from radar2shape.models.base import Reconstruction, ReconstructionModel
from radar2shape.nn.diffusion import GaussianDiffusion, drop_condition, guided
from radar2shape.nn.unet1d import UNet1D
from radar2shape.radar.spec import RadarSpec

# Normalised profiles have r in [0, 0.5] and z in [-0.5, 0.5]; this affine map sends both to
# [-1, 1], the scale the diffusion prior N(0, I) and the regression targets are built for.
PROFILE_CENTRE = (0.25, 0.0)
PROFILE_SCALE = (4.0, 2.0)
MIN_RADIUS = 1e-3  # interior points are kept off the axis: a profile may touch it only at its ends
MIN_HEIGHT = 1e-3


def normalise_profile(profile: torch.Tensor) -> torch.Tensor:
    """``[..., P, 2]`` (r, z) in unit-cube coordinates -> network scale (about [-1, 1])."""
    centre, scale = profile.new_tensor(PROFILE_CENTRE), profile.new_tensor(PROFILE_SCALE)
    return (profile - centre) * scale


def denormalise_profile(x: torch.Tensor) -> torch.Tensor:
    """Inverse of :func:`normalise_profile`."""
    centre, scale = x.new_tensor(PROFILE_CENTRE), x.new_tensor(PROFILE_SCALE)
    return x / scale + centre


def to_valid_profile(profile: np.ndarray) -> np.ndarray:
    """The closest simple fix of a predicted profile: ``r >= 0`` (interior ``r >= MIN_RADIUS``),
    ``z`` made non-decreasing by a running maximum, and at least ``MIN_HEIGHT`` tall.

    Networks are free to output anything; this keeps every prediction a solid of revolution so
    the metrics always get a mesh, while the ground truth is validated strictly instead.
    """
    profile = np.array(profile, dtype=np.float64)
    r = np.clip(profile[:, 0], 0.0, None)
    r[1:-1] = np.maximum(r[1:-1], MIN_RADIUS)
    if r.max() < MIN_RADIUS:
        r[:] = MIN_RADIUS
    z = np.maximum.accumulate(profile[:, 1])
    if z[-1] - z[0] < MIN_HEIGHT:
        z = z.mean() + np.linspace(-MIN_HEIGHT / 2, MIN_HEIGHT / 2, len(z))
    return np.column_stack([r, z])


class ProfileModel(ReconstructionModel):
    """Base of the roll-symmetric models: checked inputs, profile scaling, meshes for the metrics.

    Subclasses implement :meth:`predict_normalised` (``batch -> [B, P, 2]`` at network scale) and
    :meth:`~ReconstructionModel.losses`; everything a metric needs comes from here.
    """

    # The grid and profile sizes every roll-symmetric model declares as hyperparameters.
    num_aspect = property(lambda self: int(self.hparams.num_aspect))
    num_freq = property(lambda self: int(self.hparams.num_freq))
    profile_points = property(lambda self: int(self.hparams.profile_points))
    mesh_segments = property(lambda self: int(self.hparams.get("mesh_segments", 64)))

    def radar_input(self, batch: dict) -> torch.Tensor:
        """``[B, F + 1, A]``: the radar's frequencies as channels plus the observed-aspect mask.

        Masked aspects are zero (the DataModule's convention) and flagged by the mask channel, so
        "unobserved" is never confused with "a response at the mean level".
        """
        radar, mask = batch["radar"], batch.get("radar_mask")
        expected = (self.num_aspect, self.num_freq)
        if radar.dim() != 3 or tuple(radar.shape[1:]) != expected:
            raise UserInputError(
                f"batch['radar']: expected roll-symmetric radar [B, {expected[0]}, {expected[1]}] (aspect, frequency), "
                f"got {list(radar.shape)}; set the model's num_aspect/num_freq to the dataset's grid"
            )
        if mask is None:
            mask = torch.ones(radar.shape[:2], dtype=torch.bool, device=radar.device)
        if tuple(mask.shape) != tuple(radar.shape[:2]):
            raise UserInputError(f"batch['radar_mask']: expected [B, A] = {list(radar.shape[:2])}, got {list(mask.shape)}")
        radar = radar * mask[..., None]
        return torch.cat([radar.transpose(1, 2), mask[:, None].to(radar.dtype)], dim=1)

    def check_radar_spec(self, spec: RadarSpec) -> None:
        """The data must be aspect-only (roll-symmetric) on ``num_aspect`` x ``num_freq``."""
        aspect, _, freq = spec.grid.shape
        if not spec.roll_symmetric or (aspect, freq) != (self.num_aspect, self.num_freq):
            raise UserInputError(
                f"{type(self).__name__}: expects roll-symmetric radar [A={self.num_aspect}, F={self.num_freq}], the "
                f"data's radar spec is {spec.describe()}; set num_aspect/num_freq or use a ProfileDataModule"
            )

    def target_profiles(self, batch: dict) -> torch.Tensor:
        """The batch's ground-truth profiles at network scale, after checking each is a valid profile."""
        profile = batch.get("profile")
        if profile is None:
            raise UserInputError("batch has no 'profile'; roll-symmetric models need a ProfileDataModule (frusta)")
        if profile.dim() != 3 or profile.shape[-1] != 2:
            raise UserInputError(f"batch['profile']: expected [B, P, 2] (r, z) points, got {list(profile.shape)}")
        for i, sample in enumerate(profile.detach().cpu().numpy()):
            validate_profile(sample, name=f"batch['profile'][{i}]")
        if profile.shape[1] != self.profile_points:
            raise UserInputError(
                f"batch['profile']: {profile.shape[1]} points per profile, the model was built for "
                f"profile_points={self.profile_points}"
            )
        return normalise_profile(profile.float())

    def predict_normalised(self, batch: dict) -> torch.Tensor:
        """The model's profiles ``[B, P, 2]`` at network scale (what the subclass is about)."""
        raise NotImplementedError

    @torch.no_grad()
    def predict_profiles(self, batch: dict) -> list[np.ndarray]:
        """One valid profile ``[P, 2]`` (unit-cube coordinates) per sample."""
        profiles = denormalise_profile(self.predict_normalised(batch)).cpu().numpy()
        return [to_valid_profile(p) for p in profiles]

    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        """Predicted profiles revolved into watertight meshes (``mesh_segments`` sectors), each with its profile."""
        out = []
        for profile in self.predict_profiles(batch):
            try:
                mesh = profile_to_mesh(profile, self.mesh_segments)
            except (UserInputError, ValueError):  # e.g. a self-intersecting outline
                mesh = trimesh.Trimesh()
            out.append(Reconstruction(mesh=mesh, profile=profile))
        return out


# How the draws of one input ``[K, B, P, 2]`` become its profile ``[B, P, 2]``.
SAMPLE_REDUCTIONS = {
    "mean": lambda draws: draws.mean(dim=0),
    "median": lambda draws: draws.quantile(0.5, dim=0),  # the mid-point of the middle two when K is even
}


class ProfileUNetDiffusion(ProfileModel):
    """DDPM over profile parameters with a 1D U-Net over aspect as the denoiser (docs/design.md section 2).

    Denoiser, for a noisy normalised profile ``h_t [B, P, 2]`` and radar ``R [B, A, F]``:
      1. ``h_t`` flattened to ``2P`` -> one Linear + ReLU to ``profile_channels * A`` -> reshaped
         ``[B, profile_channels, A]``. The paper maps to one channel of aspect length
         (``profile_channels=1``); 16 channels fit 8 training shapes far better (docs/rollsym.md);
      2. concatenated along channels with ``R`` transposed to ``[B, F, A]`` and the observed-aspect
         mask ``[B, 1, A]``;
      3. a timestep-conditioned :class:`UNet1D` over aspect -> ``[B, out_channels, A]``;
      4. flattened to ``out_channels * A`` -> one Linear back to ``2P``: the predicted noise.
         Aspect positions carry no fixed relation to profile points, so the projection back is
         a dense layer over all aspects (the mirror of step 1) rather than a per-aspect readout.
         ``noisy_skip`` adds a Linear of ``h_t`` itself, so the identity-like part of the noise
         estimate (dominant at high noise) need not squeeze through the ReLU bottleneck.
    Loss: MSE between predicted and true noise (epsilon prediction) at uniform timesteps;
    ``min_snr_gamma`` weights it by ``min(SNR, gamma) / SNR`` (Hang et al. 2023), which shifts weight
    to the noisy steps where the radar decides the global shape. Sampling: DDPM ancestral over all
    steps, or DDIM with ``sample_steps``; ``num_samples > 1`` combines that many draws point-wise by
    ``sample_reduce``: their mean (the posterior mean) or their median (what a regressor trained
    with an L1 loss estimates, and a summary no single stray draw can pull).
    Classifier-free guidance: ``cond_drop`` trains that share of samples on the all-zero "nothing
    observed" input, and ``guidance`` > 1 samples with ``eps_u + guidance (eps_c - eps_u)``.
    ``lr_decay_steps`` / ``lr_decay`` (a step schedule) and ``ema_decay`` (weight averaging) are the
    base model's, as for the 3D Stage 2.
    """

    def __init__(
        self,
        num_aspect: int,
        num_freq: int,
        profile_points: int = 16,
        profile_channels: int = 16,
        base_channels: int = 32,
        depth: int = 2,
        time_dim: int = 64,
        out_channels: int = 8,
        noisy_skip: bool = True,
        num_steps: int = 1000,
        schedule: str = "cosine",
        sampler: str = "ddpm",
        sample_steps: int = 50,
        clip_x0: float | None = 1.0,
        min_snr_gamma: float | None = 5.0,
        num_samples: int = 1,
        sample_reduce: str = "mean",
        sample_seed: int = 0,
        lr: float = 1e-3,
        weight_decay: float = 0.0,
        lr_decay_steps: int = 0,
        lr_decay: float = 0.5,
        ema_decay: float = 0.0,
        mesh_segments: int = 64,
        cond_drop: float = 0.0,
        guidance: float = 1.0,
    ) -> None:
        super().__init__()
        if sample_reduce not in SAMPLE_REDUCTIONS:
            raise UserInputError(f"ProfileUNetDiffusion: sample_reduce must be one of {sorted(SAMPLE_REDUCTIONS)}, "
                                 f"got {sample_reduce!r}")
        self.save_hyperparameters()
        n_params = 2 * profile_points
        self.profile_in = nn.Linear(n_params, profile_channels * num_aspect)
        self.unet = UNet1D(num_freq + 1 + profile_channels, out_channels, base_channels, depth, time_dim=time_dim)
        self.profile_out = nn.Linear(out_channels * num_aspect, n_params)
        self.skip = nn.Linear(n_params, n_params) if noisy_skip else None
        self.diffusion = GaussianDiffusion(num_steps, schedule, clip_x0=clip_x0)

    def denoise(self, h_t: torch.Tensor, t: torch.Tensor, radar_input: torch.Tensor) -> torch.Tensor:
        """Predicted noise ``[B, P, 2]`` for ``h_t [B, P, 2]`` at timesteps ``t [B]``."""
        b = h_t.shape[0]
        h = F.relu(self.profile_in(h_t.flatten(1))).view(b, self.hparams.profile_channels, self.num_aspect)
        eps = self.profile_out(self.unet(torch.cat([radar_input, h], dim=1), t).flatten(1))
        if self.skip is not None:
            eps = eps + self.skip(h_t.flatten(1))
        return eps.view_as(h_t)

    def null_input(self, batch_size: int, like: torch.Tensor) -> torch.Tensor:
        """The "nothing observed" radar input ``[B, F + 1, A]`` (all zero): the unconditional model."""
        return like.new_zeros(batch_size, self.num_freq + 1, self.num_aspect)

    def diffusion_loss(self, batch: dict) -> torch.Tensor:
        x0 = self.target_profiles(batch)
        noise = torch.randn_like(x0)
        t = self.diffusion.sample_timesteps(x0.shape[0], device=x0.device)
        radar_input = self.radar_input(batch)
        if self.training and self.hparams.get("cond_drop", 0.0) > 0:  # guidance: learn the unconditional too
            radar_input, _ = drop_condition(radar_input, radar_input[:, -1] > 0.5, self.hparams.cond_drop)
        eps = self.denoise(self.diffusion.q_sample(x0, t, noise), t, radar_input)
        per_sample = (eps - noise).pow(2).flatten(1).mean(dim=1)
        if self.hparams.min_snr_gamma is not None:  # Hang et al. 2023, for epsilon prediction
            snr = self.diffusion.alphas_bar[t] / (1 - self.diffusion.alphas_bar[t])
            per_sample = per_sample * snr.clamp(max=self.hparams.min_snr_gamma) / snr
        return per_sample.mean()

    def losses(self, batch: dict) -> dict[str, torch.Tensor]:
        return {"loss": self.diffusion_loss(batch)}

    def predict_normalised(self, batch: dict) -> torch.Tensor:
        """Sampled profiles at network scale: ``num_samples`` draws combined point-wise by ``sample_reduce``.

        One draw is a sample of the posterior p(profile | radar); the mean of k draws estimates the
        posterior mean and their median the posterior median, each trading diversity for expected
        accuracy (docs/rollsym.md: with 32 draws the median scores best). Seeded, so a test is
        reproducible.
        """
        hp = self.hparams
        radar_input = self.radar_input(batch)
        b, k = radar_input.shape[0], hp.num_samples
        repeated = radar_input.repeat(k, 1, 1)
        generator = torch.Generator(device=radar_input.device).manual_seed(hp.sample_seed)
        null = self.null_input(k * b, repeated)
        eps_fn = guided(lambda x, t: self.denoise(x, t, repeated), lambda x, t: self.denoise(x, t, null),
                        float(hp.get("guidance", 1.0)))
        samples = self.diffusion.sample(
            eps_fn, (k * b, self.profile_points, 2), method=hp.sampler,
            steps=hp.sample_steps if hp.sampler == "ddim" else None, generator=generator, device=radar_input.device,
        )
        return SAMPLE_REDUCTIONS[hp.get("sample_reduce", "mean")](samples.view(k, b, self.profile_points, 2))
