"""A learned verifier over K Stage-2 samples: which candidate to return, and how good it likely is.

Stage 2 draws K latents per radar input, and the best of them is often much better than the first
(reports/shipped-model/verifier_parts_unseen.md,
reports/real-shipped/verifier_real_test.md). Re-simulating candidates with PO does not rank
them: a smooth reconstruction's radar differs from the truth's in fine interference whatever its
IoU. What does rank them is what the model itself says about each candidate:

- consensus: how much its occupancy agrees with its K-1 siblings' on shared probe points, and
  with the occupancy of their mean SDF (a candidate that many samples confirm is less likely an
  outlier);
- its latent's distance from the K-sample mean, per level (standardised units);
- how well the radar-conditioned denoiser explains it: the denoising error of the candidate,
  noised with one shared noise draw at a few noise levels (a Monte-Carlo slice of the
  conditional likelihood; the same draw for every candidate makes the comparison paired).

A small MLP maps these features to the candidate's IoU. The mean SDF of its ``KEEP`` best-scored
candidates is returned (averaging the few it trusts most beats its single pick: on the real test
objects by +0.03 IoU, on parts_unseen by +0.002; the reports above), and their mean predicted IoU is
a confidence. The shape-level means of the features go in too, so the prediction is
calibrated across inputs, not only within one.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import torch
from torch import nn

from radar2shape.errors import UserInputError

PROBE_POINTS = 16384
NOISE_LEVELS = (0.2, 0.4, 0.6, 0.8)  # fractions of the model's diffusion steps
FORMAT = "radar2shape-verifier/1"
KEEP = 3  # best-scored candidates whose mean SDF is returned


def probe_points(bound: float, count: int = PROBE_POINTS, seed: int = 0) -> torch.Tensor:
    """``count`` points uniform in the model's cube ``[-bound, bound]^3``, the same for every input."""
    generator = torch.Generator().manual_seed(seed)
    return (torch.rand(count, 3, generator=generator) * 2 - 1) * bound


def occupancy_iou(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """IoU of boolean occupancies ``a [K, P]`` and ``b [K, P]`` (or ``[P]``, broadcast); 0 when both empty."""
    inter = (a & b).sum(-1).float()
    union = (a | b).sum(-1).float()
    return torch.where(union > 0, inter / union.clamp_min(1), torch.zeros_like(inter))


def feature_names(n_levels: int) -> list[str]:
    """Names of the columns of :func:`candidate_features`, in order."""
    per_candidate = ["consensus", "iou_with_mean", "log_volume_ratio"]
    per_candidate += [f"latent_distance_l{level}" for level in range(n_levels)]
    per_candidate += [f"log_denoise_ratio_{f:g}" for f in NOISE_LEVELS]
    per_shape = ["mean_consensus", "log_mean_volume"] + [f"log_denoise_{f:g}" for f in NOISE_LEVELS]
    return per_candidate + per_shape


@torch.no_grad()
def candidate_features(model, radar_tokens: torch.Tensor, latents: torch.Tensor, probe: torch.Tensor) -> torch.Tensor:
    """Features ``[K, F]`` of the K candidate latents ``[K, L, Z]`` of one input (radar tokens ``[1, L, D]``)."""
    k = latents.shape[0]
    if k < 2:
        raise UserInputError(f"the verifier compares candidates: need at least 2, got {k}")
    sdf = model.sdf_function(latents)(probe)  # [K, P]
    occupied = sdf < 0
    pair = occupancy_iou(occupied[:, None], occupied[None])  # [K, K], 1 on the diagonal
    consensus = (pair.sum(1) - 1) / (k - 1)
    with_mean = occupancy_iou(occupied, sdf.mean(0) < 0)
    volume = occupied.float().mean(1)
    log_volume_ratio = torch.log((volume + 1e-4) / (volume.mean() + 1e-4))

    z = model.standardiser(latents)
    distance = (z - z.mean(0)).pow(2).mean(-1)  # [K, L]
    distance = distance / distance.mean(0).clamp_min(1e-8)

    steps = model.diffusion.num_steps
    generator = torch.Generator().manual_seed(0)
    tokens = radar_tokens.expand(k, -1, -1)
    errors = []
    for fraction in NOISE_LEVELS:
        t = torch.full((k,), min(steps - 1, int(round(fraction * steps))), dtype=torch.long)
        noise = torch.randn(z.shape[1:], generator=generator).expand_as(z)
        h_t = model.diffusion.q_sample(z, t, noise)
        errors.append((model.denoise_tokens(tokens, h_t, t) - noise).pow(2).mean((1, 2)))
    errors = torch.stack(errors, 1).clamp_min(1e-12)  # [K, levels]
    log_ratio = torch.log(errors / errors.mean(0))

    per_candidate = torch.cat([consensus[:, None], with_mean[:, None], log_volume_ratio[:, None], distance,
                               log_ratio], 1)
    per_shape = torch.cat([consensus.mean()[None], torch.log(volume.mean() + 1e-4)[None], torch.log(errors.mean(0))])
    return torch.cat([per_candidate, per_shape.expand(k, -1)], 1)


class Verifier(nn.Module):
    """Features ``[..., F]`` -> predicted IoU ``[...]``: input standardisation, then a two-layer MLP."""

    def __init__(self, n_features: int, hidden: int = 64) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(n_features))
        self.register_buffer("std", torch.ones(n_features))
        self.net = nn.Sequential(nn.Linear(n_features, hidden), nn.SiLU(), nn.Linear(hidden, hidden), nn.SiLU(),
                                 nn.Linear(hidden, 1))

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return self.net((features - self.mean) / self.std).squeeze(-1)


def verifier_loss(predicted: torch.Tensor, iou: torch.Tensor, temperature: float = 0.05) -> torch.Tensor:
    """Squared error on IoU plus a listwise term: the softmax over the K candidates of the prediction
    against that of the true IoU (cross-entropy), so the ranking within one input is learnt too."""
    target = torch.softmax(iou / temperature, -1)
    listwise = -(target * torch.log_softmax(predicted / temperature, -1)).sum(-1).mean()
    return (predicted - iou).pow(2).mean() + temperature * listwise


def fit_verifier(features: torch.Tensor, iou: torch.Tensor, epochs: int = 400, lr: float = 3e-3,
                 weight_decay: float = 1e-3, hidden: int = 64, seed: int = 0) -> Verifier:
    """Train on ``features [N, K, F]`` and candidate IoUs ``[N, K]`` (full batch, AdamW, fixed seed)."""
    if features.dim() != 3 or iou.shape != features.shape[:2]:
        raise UserInputError(f"verifier data: features [N, K, F] and IoU [N, K] expected, got "
                             f"{tuple(features.shape)} and {tuple(iou.shape)}")
    torch.manual_seed(seed)
    verifier = Verifier(features.shape[-1], hidden)
    flat = features.reshape(-1, features.shape[-1])
    verifier.mean.copy_(flat.mean(0))
    verifier.std.copy_(flat.std(0).clamp_min(1e-6))
    optimiser = torch.optim.AdamW(verifier.parameters(), lr=lr, weight_decay=weight_decay)
    for _ in range(epochs):
        optimiser.zero_grad()
        loss = verifier_loss(verifier(features), iou)
        loss.backward()
        optimiser.step()
    return verifier.eval()


def save_verifier(verifier: Verifier, path: Path, n_levels: int, about: dict) -> None:
    """Write the verifier (weights, feature names, what it was trained on) atomically."""
    from radar2shape.atomic import atomic_path

    payload = {"format": FORMAT, "state_dict": verifier.state_dict(), "hidden": verifier.net[0].out_features,
               "features": feature_names(n_levels), "noise_levels": list(NOISE_LEVELS), "probe_points": PROBE_POINTS,
               "about": about}
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)


def load_verifier(path: Path, n_levels: int, candidates: int | None = None) -> Verifier:
    """A verifier file for a model with ``n_levels`` latent levels; one clear error when it does not fit.

    ``candidates``: the K it will choose among, refused when the file was trained on another K. Its
    features are relative to the K siblings, so the choice does not carry over: the shipped verifier
    (K = 8) used on K = 16 fell below the first sample (docs/metrics.md).
    """
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except (OSError, RuntimeError, EOFError, pickle.UnpicklingError) as error:
        raise UserInputError(f"{path}: not a readable verifier file ({error})") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise UserInputError(f"{path}: not a verifier file (expected format {FORMAT})")
    names = feature_names(n_levels)
    if payload["features"] != names or payload["noise_levels"] != list(NOISE_LEVELS):
        raise UserInputError(f"{path}: its features ({len(payload['features'])}) do not match this model's "
                             f"({len(names)}, {n_levels} latent levels)")
    trained_k = (payload.get("about") or {}).get("candidates")
    if candidates is not None and trained_k is not None and int(trained_k) != candidates:
        raise UserInputError(f"{path}: trained to choose among K = {trained_k} candidates, not {candidates}; "
                             f"use --candidates {trained_k} or train one for K = {candidates} "
                             f"(scripts/train_verifier.py --candidates {candidates})")
    verifier = Verifier(len(names), payload["hidden"])
    verifier.load_state_dict(payload["state_dict"])
    return verifier.eval()


def default_verifier_path(checkpoint: Path) -> Path:
    """Where a checkpoint's verifier lives: beside it, ``<stem>.verifier.pt``."""
    return Path(checkpoint).with_suffix(".verifier.pt")


@torch.no_grad()
def score_candidates(model, verifier: Verifier, batch: dict, num_samples: int, steps: int | None = None,
                     sample_seed: int | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """K latents for a one-input batch and the verifier's predicted IoU of each: ``([K, L, Z], [K])``."""
    latents = model.sample_latents(batch, num_samples=num_samples, steps=steps, sample_seed=sample_seed)[0]
    tokens = model.encode_radar(batch["radar"].to(model.device), batch["radar_mask"].to(model.device))
    probe = probe_points(float(model.stage1.hparams.bound))
    return latents, verifier(candidate_features(model, tokens, latents, probe))


def kept_candidates(predicted: torch.Tensor, keep: int) -> torch.Tensor:
    """Indices of the ``keep`` candidates with the highest predicted IoU ``[K]``, best first (ties: lower index)."""
    if not 1 <= keep <= predicted.shape[-1]:
        raise UserInputError(f"keep: expected 1 to {predicted.shape[-1]} of the K candidates, got {keep}")
    return torch.argsort(predicted, descending=True, stable=True)[:keep]


@torch.no_grad()
def verified_latents(model, verifier: Verifier, batch: dict, num_samples: int, keep: int = KEEP,
                     steps: int | None = None, sample_seed: int | None = None,
                     ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """For a one-input batch: ``(all K latents [K, L, Z], predicted IoUs [K], kept indices [keep])``;
    the returned shape is the mean SDF of ``latents[kept]``, its confidence ``predicted[kept].mean()``."""
    latents, predicted = score_candidates(model, verifier, batch, num_samples, steps, sample_seed)
    return latents, predicted, kept_candidates(predicted, keep)
