"""The InvRT baseline: masking by key padding, bad inputs, overfitting eight simulated frusta."""

import time

import numpy as np
import pytest
import torch

from baselines.invrt import InvRT
from models.test_profile_diffusion import N_ASPECT, N_FREQ, frusta_batch, mean_section_iou, one_thread, train  # noqa: F401
from radar2shape.errors import UserInputError

TINY = dict(num_aspect=N_ASPECT, num_freq=N_FREQ, dim=64, n_layers=2, n_heads=4)


@pytest.fixture(scope="module")
def batch():
    return frusta_batch()


def test_unobserved_aspects_do_not_change_the_prediction(batch):
    model = InvRT(**TINY).eval()
    mask = torch.arange(N_ASPECT).expand(8, -1) >= 5  # aspects 0-4 unobserved
    observed = dict(batch, radar_mask=mask)
    scrambled = dict(observed, radar=torch.where(mask[..., None], batch["radar"], 100 * torch.randn(8, N_ASPECT, N_FREQ)))
    out = model.predict_normalised(observed)
    assert out.shape == (8, 16, 2)
    torch.testing.assert_close(model.predict_normalised(scrambled), out)
    assert not torch.allclose(model.predict_normalised(batch), out)  # the mask itself matters


@pytest.mark.parametrize(
    "profile, message",
    [
        (torch.tensor([[[0.2, 0.0]]]), "at least two"),
        (torch.tensor([[[0.2, -0.3], [-0.1, 0.3]]]), "radii must be >= 0"),
        (torch.tensor([[[0.2, 0.3], [0.3, -0.3]]]), "non-decreasing"),
    ],
)
def test_bad_profiles_raise_clear_errors(batch, profile, message):
    with pytest.raises(UserInputError, match=message):
        InvRT(**TINY).training_step(dict(batch, profile=profile.expand(8, -1, -1)), 0)


def test_unknown_loss_is_refused():
    with pytest.raises(ValueError, match="loss"):
        InvRT(**TINY, loss="huber")


def test_overfits_eight_profiles(batch):
    """IoU-S >= 0.8 on the 8 training shapes in 300 steps (about 10 s on 2 free cores)."""
    torch.manual_seed(0)
    start = time.perf_counter()
    model = InvRT(**TINY)
    losses = train(model, batch, lambda b: model.losses(b)["loss"], steps=300)
    iou = mean_section_iou(model, batch)
    print(f"InvRT overfit: IoU-S {iou:.3f}, loss {losses[0]:.3f} -> {losses[-1]:.3f} in {time.perf_counter() - start:.0f} s")
    assert losses[-1] < 0.3 * losses[0]
    assert iou >= 0.8
    recs = model.reconstruct(batch)
    assert all(r.mesh.is_watertight for r in recs) and np.isfinite(recs[0].profile).all()
