"""The profile U-Net diffusion model: shapes, masks, bad inputs, meshes, learning and overfitting.

``frusta_batch`` (also used by tests/baselines/test_invrt.py) simulates eight random frusta on
the tiny radar grid with the project's simulator, so the radar really determines the shape.
"""

import time

import numpy as np
import pytest
import torch

from radar2shape.errors import UserInputError
from radar2shape.geometry.families.frusta import random_profile
from radar2shape.geometry.normalise import normalisation
from radar2shape.geometry.profile import resample_profile
from radar2shape.metrics.rollsym import profile_radar_db, section_iou
from radar2shape.models.base import Reconstruction
from radar2shape.models.profile_diffusion import (
    ProfileUNetDiffusion,
    denormalise_profile,
    normalise_profile,
    to_valid_profile,
)
from radar2shape.nn.unet1d import UNet1D
from radar2shape.radar import RadarGrid

N_ASPECT = N_FREQ = 16
TINY_UNET = dict(num_aspect=N_ASPECT, num_freq=N_FREQ, base_channels=16, time_dim=32, num_steps=100, lr=3e-3)


def unit_profile(profile: np.ndarray) -> np.ndarray:
    """A profile in the unit-cube frame of its solid (bbox centre at 0, longest side 1)."""
    r, z = profile.T
    centre, scale = normalisation(np.column_stack([np.r_[r, -r], np.zeros(2 * len(r)), np.r_[z, z]]))
    return (profile - [0.0, centre[2]]) * scale


def frusta_batch(n: int = 8, points: int = 16, seed: int = 0) -> dict:
    """``n`` random frusta stacks (1-3 frusta) with their standardised dB radar on the tiny grid."""
    grid = RadarGrid.from_config({"aspect_deg": {"start": 0, "stop": 180, "count": N_ASPECT},
                                  "freq_ghz": {"start": 8, "stop": 12, "count": N_FREQ}})
    rng = np.random.default_rng(seed)
    profiles = np.stack([unit_profile(resample_profile(random_profile(rng, 1 + i % 3), points)) for i in range(n)])
    db = np.stack([profile_radar_db(p, grid.aspect_rad, grid.freq_hz, grid.size_m, segments=32) for p in profiles])
    return {
        "radar": torch.tensor((db - db.mean()) / db.std(), dtype=torch.float32),
        "radar_mask": torch.ones(n, N_ASPECT, dtype=torch.bool),
        "profile": torch.tensor(profiles, dtype=torch.float32),
        "label": torch.zeros(n, dtype=torch.long),
        "index": torch.arange(n),
    }


def train(model, batch: dict, loss_fn, steps: int, repeat: int = 1) -> list[float]:
    """Full-batch steps with the model's optimiser (batch repeated: more timesteps per step)."""
    batch = {k: v.repeat_interleave(repeat, 0) for k, v in batch.items()}
    optimizer = model.configure_optimizers()
    model.train()
    losses = []
    for _ in range(steps):
        loss = loss_fn(batch)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        losses.append(loss.item())
    model.eval()
    return losses


def mean_section_iou(model, batch: dict) -> float:
    return float(np.mean([section_iou(p, g) for p, g in zip(model.predict_profiles(batch), batch["profile"].numpy())]))


@pytest.fixture(scope="module", autouse=True)
def one_thread():
    """One torch thread: these tiny models gain nothing from more, and on a busy 2-core machine
    two threads per process made the steps up to 30x slower."""
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


@pytest.fixture(scope="module")
def batch():
    return frusta_batch()


@pytest.mark.parametrize("length", [16, 15, 7])
def test_unet1d_keeps_length_and_uses_the_timestep(length):
    net = UNet1D(5, 3, base_channels=8, depth=2, time_dim=16)
    x = torch.randn(2, 5, length)
    out = net(x, torch.tensor([0, 50]))
    assert out.shape == (2, 3, length)
    assert not torch.allclose(out, net(x, torch.tensor([7, 50])))


def test_profile_normalisation_round_trip_and_range():
    profile = torch.tensor([[0.0, -0.5], [0.5, -0.2], [0.25, 0.5]])
    x = normalise_profile(profile)
    assert x.min() == -1 and x.max() == 1
    torch.testing.assert_close(denormalise_profile(x), profile)


def test_invalid_predictions_become_valid_profiles():
    fixed = to_valid_profile(np.array([[-0.1, 0.2], [0.3, 0.1], [-0.2, 0.4], [0.1, 0.3]]))
    assert (fixed[:, 0] >= 0).all() and (fixed[1:-1, 0] > 0).all() and (np.diff(fixed[:, 1]) >= 0).all()
    flat = to_valid_profile(np.array([[0.2, 0.1], [0.2, 0.1]]))
    assert flat[-1, 1] > flat[0, 1]


def test_denoiser_shapes_and_masked_aspects_are_ignored(batch):
    model = ProfileUNetDiffusion(**TINY_UNET)
    masked = dict(batch, radar_mask=torch.arange(N_ASPECT).expand(8, -1) < 10)
    h_t, t = torch.randn(8, 16, 2), torch.full((8,), 40)
    eps = model.denoise(h_t, t, model.radar_input(masked))
    assert eps.shape == (8, 16, 2)
    scrambled = dict(masked, radar=torch.where(masked["radar_mask"][..., None], masked["radar"], torch.randn(8, N_ASPECT, N_FREQ)))
    torch.testing.assert_close(model.denoise(h_t, t, model.radar_input(scrambled)), eps)
    channels = model.radar_input(masked)
    assert channels.shape == (8, N_FREQ + 1, N_ASPECT) and (channels[:, -1].sum(1) == 10).all()


@pytest.mark.parametrize(
    "profile, message",
    [
        (torch.tensor([[[0.2, 0.0]]]), "at least two"),
        (torch.tensor([[[0.2, -0.3], [-0.1, 0.3]]]), "radii must be >= 0"),
        (torch.tensor([[[0.2, 0.3], [0.3, -0.3]]]), "non-decreasing"),
        (torch.zeros(1, 4), r"\[B, P, 2\]"),
    ],
)
def test_bad_profiles_in_the_batch_raise_clear_errors(batch, profile, message):
    model = ProfileUNetDiffusion(**TINY_UNET)
    bad = dict(batch, profile=profile.expand(8, *profile.shape[1:]) if profile.dim() == 3 else profile)
    with pytest.raises(UserInputError, match=message):
        model.training_step(bad, 0)


def test_wrong_radar_grid_or_profile_length_raise_clear_errors(batch):
    model = ProfileUNetDiffusion(**TINY_UNET)
    with pytest.raises(UserInputError, match="num_aspect"):
        model.diffusion_loss(dict(batch, radar=batch["radar"][:, :12], radar_mask=batch["radar_mask"][:, :12]))
    with pytest.raises(UserInputError, match="profile_points=16"):
        model.diffusion_loss(dict(batch, profile=torch.tensor(np.stack([resample_profile(p, 20) for p in batch["profile"].numpy()]))))


def test_reconstruct_gives_watertight_meshes_reproducibly(batch):
    model = ProfileUNetDiffusion(**TINY_UNET, num_samples=2).eval()
    recs = model.reconstruct(batch)
    assert len(recs) == 8 and all(isinstance(r, Reconstruction) for r in recs)
    assert all(r.mesh.is_watertight and r.profile.shape == (16, 2) for r in recs)
    model.train()
    again = model.eval().reconstruct(batch)
    assert all(np.allclose(a.profile, r.profile) for a, r in zip(again, recs))  # seeded sampling


def test_learns_quickly(batch):
    """Fast check (about 10 s on 2 free cores): 150 steps halve the loss and beat an untrained model's IoU-S."""
    torch.manual_seed(0)
    model = ProfileUNetDiffusion(**TINY_UNET)
    before = mean_section_iou(model.eval(), batch)
    losses = train(model, batch, model.diffusion_loss, steps=150, repeat=4)
    assert np.mean(losses[-20:]) < 0.5 * np.mean(losses[:20])
    after = mean_section_iou(model, batch)
    print(f"profile U-Net, 150 steps: IoU-S {before:.3f} -> {after:.3f}, loss {np.mean(losses[:20]):.3f} -> {np.mean(losses[-20:]):.3f}")
    assert after > max(before + 0.1, 0.4), (before, after)


@pytest.mark.slow
def test_overfits_eight_profiles(batch):
    """IoU-S >= 0.8 on the 8 training shapes; about 60-90 s on 2 free cores (budget 240 s)."""
    torch.manual_seed(0)
    start = time.perf_counter()
    model = ProfileUNetDiffusion(**TINY_UNET, num_samples=4)
    train(model, batch, model.diffusion_loss, steps=1500, repeat=4)
    iou = mean_section_iou(model, batch)
    print(f"profile U-Net overfit: IoU-S {iou:.3f} in {time.perf_counter() - start:.0f} s")
    assert iou >= 0.8


def test_guidance_zero_ignores_the_radar_and_condition_dropout_trains(batch):
    """guidance = 0 samples the unconditional model: two different radars give the same profiles;
    guidance = 1 (default) reads the radar; cond_drop blanks the radar of some training samples."""
    model = ProfileUNetDiffusion(**TINY_UNET, guidance=0.0, num_samples=1).eval()
    other = {**batch, "radar": torch.randn_like(batch["radar"])}
    torch.testing.assert_close(model.predict_normalised(batch), model.predict_normalised(other))
    model.hparams.guidance = 1.0
    assert not torch.allclose(model.predict_normalised(batch), model.predict_normalised(other))
    dropping = ProfileUNetDiffusion(**TINY_UNET, cond_drop=1.0).train()
    seen = []
    dropping.denoise = lambda h_t, t, radar_input: seen.append(radar_input) or torch.zeros_like(h_t)
    dropping.diffusion_loss(batch)
    assert not seen[0].any()  # cond_drop = 1: every sample sees "nothing observed"


@pytest.mark.parametrize("reduce, expected", [("mean", [[2.5, 25.0]]), ("median", [[1.5, 15.0]])])
def test_draws_are_combined_point_wise_by_sample_reduce(batch, reduce, expected):
    """Four draws of one input, one point: (1, 10), (2, 20), (1, 10), (6, 60) -> mean (2.5, 25), median (1.5, 15)."""
    model = ProfileUNetDiffusion(**TINY_UNET, num_samples=4, sample_reduce=reduce).eval()
    draws = torch.tensor([1.0, 2.0, 1.0, 6.0])
    b = batch["radar"].shape[0]

    def fake_sample(eps_fn, shape, **kwargs):  # draw j of every input holds draws[j] at every point
        assert shape == (4 * b, model.profile_points, 2)
        rows = draws.repeat_interleave(b)[:, None, None]
        return torch.cat([rows, 10 * rows], dim=2).expand(-1, model.profile_points, 2)

    model.diffusion.sample = fake_sample
    out = model.predict_normalised(batch)
    torch.testing.assert_close(out, torch.tensor(expected).expand(b, model.profile_points, 2))


def test_unknown_sample_reduce_is_one_error_line():
    with pytest.raises(UserInputError, match="sample_reduce must be one of \\['mean', 'median'\\], got 'mode'"):
        ProfileUNetDiffusion(**TINY_UNET, sample_reduce="mode")
