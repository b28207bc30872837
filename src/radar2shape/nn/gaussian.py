"""Diagonal Gaussian posterior helpers for VAEs: reparameterised sampling and closed-form KL."""

from __future__ import annotations

import math

import torch


def reparameterize(mu: torch.Tensor, logvar: torch.Tensor, generator: torch.Generator | None = None) -> torch.Tensor:
    """Sample ``mu + sigma * eps`` with ``eps ~ N(0, I)``, differentiable in ``mu`` and ``logvar``."""
    eps = torch.randn(mu.shape, generator=generator, device=mu.device, dtype=mu.dtype)
    return mu + torch.exp(0.5 * logvar) * eps


def gaussian_kl(mu: torch.Tensor, logvar: torch.Tensor, prior_std: float = 1.0) -> torch.Tensor:
    """Elementwise KL( N(mu, exp(logvar)) || N(0, prior_std**2) ), same shape as ``mu``.

    ``prior_std`` is a standard deviation, not a variance.
    """
    prior_logvar = 2.0 * math.log(prior_std)
    return 0.5 * ((logvar.exp() + mu.square()) / prior_std**2 - 1.0 - logvar + prior_logvar)
