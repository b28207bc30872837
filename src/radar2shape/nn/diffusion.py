"""Gaussian diffusion (DDPM, Ho et al. 2020) with epsilon prediction, and the DDIM sampler.

Generic over tensor shapes: ``x`` is ``[B, ...]`` (latent tokens ``[B, L, Z]`` for Radar2Shape,
profiles ``[B, P, 2]`` for the roll-symmetric U-Net); the denoiser is any
``eps_fn(x_t, t [B]) -> eps`` closure, so conditioning stays with the model.

Notation: ``alpha_t = 1 - beta_t``, ``abar_t = prod_{s<=t} alpha_s``, timesteps ``t = 0 .. T-1``,
``q(x_t | x_0) = N(sqrt(abar_t) x_0, (1 - abar_t) I)``. Each update is returned as
``(mean, std)`` so tests can compare samplers without drawing noise.

DDIM (Song et al. 2021): ``x_prev = sqrt(abar_prev) x0 + sqrt(1 - abar_prev - sigma^2) eps + sigma z``,
``sigma = eta * sqrt((1 - abar_prev) / (1 - abar_t)) * sqrt(1 - abar_t / abar_prev)``; with all
T steps and ``eta = 1``, sigma^2 is the DDPM posterior variance and the update is DDPM's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import torch
from torch import nn

EpsFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


def guided(conditional: EpsFn, unconditional: EpsFn, scale: float) -> EpsFn:
    """Classifier-free guidance (Ho & Salimans 2022): ``eps_u + scale (eps_c - eps_u)``.

    ``scale = 1`` is the plain conditional model (``unconditional`` is never called); larger
    scales push samples toward what the condition makes more likely than the prior does, the
    lever on a model that under-uses its radar. Linear in the prediction, so it applies equally to
    a velocity output.
    """
    if scale == 1.0:
        return conditional

    def eps(x: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        unconditioned = unconditional(x, t)
        return unconditioned + scale * (conditional(x, t) - unconditioned)

    return eps


def drop_condition(radar: torch.Tensor, mask: torch.Tensor, probability: float,
                   generator: torch.Generator | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Training-time condition dropout for guidance: each sample, with ``probability``, becomes
    "nothing observed" (radar zero, mask all False), the same input as a fully masked radar, so
    the unconditional model needs no extra parameters. Returns new tensors (inputs unchanged)."""
    if probability <= 0.0:
        return radar, mask
    drop = torch.rand(radar.shape[0], generator=generator, device=radar.device) < probability
    keep = (~drop).view(-1, *([1] * (mask.dim() - 1)))
    return radar * keep.view(-1, *([1] * (radar.dim() - 1))).to(radar.dtype), mask & keep


def cosine_alpha_bar(t: torch.Tensor, s: float = 0.008) -> torch.Tensor:
    """Nichol & Dhariwal (2021) ``f(t) = cos^2(pi/2 (t + s) / (1 + s))`` for ``t`` in [0, 1] (not normalised)."""
    return torch.cos((t + s) / (1 + s) * math.pi / 2) ** 2


def cosine_betas(num_steps: int, s: float = 0.008, max_beta: float = 0.999) -> torch.Tensor:
    """``beta_t = 1 - abar(t+1) / abar(t)`` from the cosine ``abar``, clipped at ``max_beta`` (float64)."""
    f = cosine_alpha_bar(torch.arange(num_steps + 1, dtype=torch.float64) / num_steps, s)
    return (1 - f[1:] / f[:-1]).clamp(max=max_beta)


def linear_betas(num_steps: int, beta_start: float = 1e-4, beta_end: float = 0.02) -> torch.Tensor:
    """Ho et al.'s linear schedule, rescaled to ``num_steps`` so that ``sum beta`` stays as for T = 1000."""
    scale = 1000.0 / num_steps
    return torch.linspace(scale * beta_start, scale * beta_end, num_steps, dtype=torch.float64)


def make_betas(schedule: str, num_steps: int) -> torch.Tensor:
    """The beta sequence of a named schedule (``"cosine"`` or ``"linear"``)."""
    if schedule == "cosine":
        return cosine_betas(num_steps)
    if schedule == "linear":
        return linear_betas(num_steps)
    raise ValueError(f"unknown noise schedule '{schedule}' (expected 'cosine' or 'linear')")


def spaced_timesteps(num_steps: int, steps: int) -> list[int]:
    """``steps`` timesteps evenly spaced over ``[0, T-1]``, descending (all of them when ``steps = T``)."""
    if not 1 <= steps <= num_steps:
        raise ValueError(f"sampling steps must be in 1..{num_steps}, got {steps}")
    return torch.linspace(num_steps - 1, 0, steps).round().long().tolist()


class GaussianDiffusion(nn.Module):
    """Noise schedule buffers plus the forward process and the DDPM/DDIM reverse updates.

    Buffers are not saved in checkpoints (they follow from ``schedule`` and ``num_steps``).
    ``clip_x0`` (optional) clamps the predicted ``x_0`` during sampling, which keeps the first
    steps of a schedule whose ``abar_{T-1}`` is tiny from amplifying small errors in ``eps``.
    """

    def __init__(self, num_steps: int = 1000, schedule: str = "cosine", clip_x0: float | None = None) -> None:
        super().__init__()
        self.num_steps = num_steps
        self.clip_x0 = clip_x0
        betas = make_betas(schedule, num_steps)
        alphas_bar = torch.cumprod(1 - betas, dim=0)
        for name, value in {
            "betas": betas,
            "alphas_bar": alphas_bar,
            "alphas_bar_prev": torch.cat([alphas_bar.new_ones(1), alphas_bar[:-1]]),
        }.items():
            self.register_buffer(name, value.float(), persistent=False)

    # ---- forward process ---------------------------------------------------------------------
    def sample_timesteps(self, batch: int, device=None, generator: torch.Generator | None = None) -> torch.Tensor:
        """Uniform integer timesteps ``[batch]`` in ``[0, T)``."""
        return torch.randint(0, self.num_steps, (batch,), device=device, generator=generator)

    def q_sample(self, x0: torch.Tensor, t: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """``x_t = sqrt(abar_t) x_0 + sqrt(1 - abar_t) noise`` for per-sample timesteps ``t [B]``."""
        abar = self._at(self.alphas_bar, t, x0)
        return abar.sqrt() * x0 + (1 - abar).sqrt() * noise

    def skip_eps(self, x_t: torch.Tensor, t: torch.Tensor, out: torch.Tensor) -> torch.Tensor:
        """Noise prediction with a fixed skip from the input: ``sqrt(1 - abar_t) x_t + sqrt(abar_t) out``.

        At high noise ``eps ~= x_t``; a network that must reproduce ``x_t`` through its layers
        leaves a small error, and ``x_0 = (x_t - sqrt(1 - abar) eps) / sqrt(abar)`` multiplies it by
        up to ``1 / sqrt(abar_{T-1})`` (10^4 for the cosine schedule): samples explode. With the
        skip, ``x_0 = sqrt(abar) x_t - sqrt(1 - abar) out`` is bounded for every ``t``: ``out`` is
        the velocity ``v`` of Salimans & Ho 2022 (:meth:`v_target`).
        """
        abar = self._at(self.alphas_bar, t, x_t)
        return (1 - abar).sqrt() * x_t + abar.sqrt() * out

    def v_target(self, x0: torch.Tensor, t: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """Velocity ``v = sqrt(abar_t) noise - sqrt(1 - abar_t) x_0``: what ``out`` of :meth:`skip_eps` should be.

        The MSE on ``v`` equals the noise MSE divided by ``abar_t``: it keeps weight on the
        high-noise steps, where the noise MSE (weight ``abar_t -> 0``) barely trains the network,
        yet where sampling from pure noise decides the coarse shape.
        """
        abar = self._at(self.alphas_bar, t, x0)
        return abar.sqrt() * noise - (1 - abar).sqrt() * x0

    # ---- reverse updates ---------------------------------------------------------------------
    def predict_x0(self, x_t: torch.Tensor, t: int, eps: torch.Tensor) -> torch.Tensor:
        """``x_0 = (x_t - sqrt(1 - abar_t) eps) / sqrt(abar_t)``, clamped when ``clip_x0`` is set."""
        abar = self.alphas_bar[t]
        x0 = (x_t - (1 - abar).sqrt() * eps) / abar.sqrt()
        return x0 if self.clip_x0 is None else x0.clamp(-self.clip_x0, self.clip_x0)

    def ddpm_update(self, x_t: torch.Tensor, t: int, eps: torch.Tensor, variance: str = "posterior"):
        """Mean and std of ``p(x_{t-1} | x_t)``: the posterior ``q(x_{t-1} | x_t, x_0)`` at the predicted ``x_0``.

        ``variance="posterior"`` uses ``beta_tilde_t = beta_t (1 - abar_{t-1}) / (1 - abar_t)``,
        ``"beta"`` uses ``beta_t`` (Ho et al. found both work); std is 0 at ``t = 0``.
        """
        beta, abar, abar_prev = self.betas[t], self.alphas_bar[t], self.alphas_bar_prev[t]
        x0 = self.predict_x0(x_t, t, eps)
        mean = (beta * abar_prev.sqrt() * x0 + (1 - abar_prev) * (1 - beta).sqrt() * x_t) / (1 - abar)
        if t == 0:
            return mean, torch.zeros_like(beta)
        if variance == "posterior":
            return mean, (beta * (1 - abar_prev) / (1 - abar)).sqrt()
        if variance == "beta":
            return mean, beta.sqrt()
        raise ValueError(f"unknown DDPM variance '{variance}' (expected 'posterior' or 'beta')")

    def ddim_update(self, x_t: torch.Tensor, t: int, t_prev: int, eps: torch.Tensor, eta: float = 0.0):
        """Mean and std of the DDIM step from ``t`` to ``t_prev`` (``-1``: to the clean sample)."""
        abar = self.alphas_bar[t]
        abar_prev = self.alphas_bar[t_prev] if t_prev >= 0 else abar.new_ones(())
        x0 = self.predict_x0(x_t, t, eps)
        if self.clip_x0 is not None:  # keep eps consistent with the clamped x0
            eps = (x_t - abar.sqrt() * x0) / (1 - abar).sqrt()
        sigma = eta * ((1 - abar_prev) / (1 - abar) * (1 - abar / abar_prev)).clamp(min=0).sqrt()
        mean = abar_prev.sqrt() * x0 + (1 - abar_prev - sigma**2).clamp(min=0).sqrt() * eps
        return mean, sigma

    # ---- samplers ----------------------------------------------------------------------------
    @torch.no_grad()
    def sample(
        self,
        eps_fn: EpsFn,
        shape: Sequence[int],
        method: str = "ddim",
        steps: int | None = None,
        eta: float = 0.0,
        generator: torch.Generator | None = None,
        device=None,
        variance: str = "posterior",
    ) -> torch.Tensor:
        """Draw ``x_0`` of ``shape`` from ``x_T ~ N(0, I)``.

        ``method="ddpm"``: ancestral sampling over all T steps. ``method="ddim"``: ``steps``
        evenly spaced steps (default all), stochasticity ``eta`` (0 = deterministic).
        """
        device = device if device is not None else self.betas.device
        x = torch.randn(tuple(shape), generator=generator, device=device)
        if method == "ddpm":
            schedule = list(range(self.num_steps - 1, -1, -1))
        elif method == "ddim":
            schedule = spaced_timesteps(self.num_steps, steps or self.num_steps)
        else:
            raise ValueError(f"unknown sampler '{method}' (expected 'ddpm' or 'ddim')")
        for i, t in enumerate(schedule):
            eps = eps_fn(x, torch.full((x.shape[0],), t, device=device, dtype=torch.long))
            if method == "ddpm":
                mean, std = self.ddpm_update(x, t, eps, variance)
            else:
                mean, std = self.ddim_update(x, t, schedule[i + 1] if i + 1 < len(schedule) else -1, eps, eta)
            x = mean if float(std) == 0.0 else mean + std * torch.randn(x.shape, generator=generator, device=device)
        return x

    @staticmethod
    def _at(values: torch.Tensor, t: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
        """``values[t]`` shaped ``[B, 1, ...]`` to broadcast against ``like [B, ...]``."""
        return values[t].reshape(-1, *([1] * (like.dim() - 1))).to(like.dtype)
