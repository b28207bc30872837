"""Triplane projection/sampling, local pooling, U-Net, VAE heads and the Gaussian KL."""

import pytest
import torch
from torch.distributions import Normal, kl_divergence

from radar2shape.nn import (
    PlaneDecoder,
    PlanePosterior,
    UNet2D,
    depth_for_resolution,
    gaussian_kl,
    local_pool,
    plane_cell_index,
    project_to_planes,
    reparameterize,
    sample_planes,
)


def test_projection_is_the_mean_of_each_cell_and_sampling_reads_cell_centres():
    torch.manual_seed(0)
    res, bound = 4, 0.5
    points = torch.rand(2, 50, 3) - 0.5
    feats = torch.randn(2, 50, 3)
    index = plane_cell_index(points, res, bound)
    planes = project_to_planes(feats, index, res)  # [2, 3, C, R, R]
    b, p, n = 1, 2, 7  # yz plane: column from y, row from z
    row, col = int((points[b, n, 2] + 0.5) * res), int((points[b, n, 1] + 0.5) * res)
    same = index[b, p] == index[b, p, n]
    torch.testing.assert_close(planes[b, p, :, row, col], feats[b][same].mean(0))
    # A plane read at a cell centre returns that cell's value (here only the xy plane is non-zero).
    only_xy = torch.zeros_like(planes)
    only_xy[:, 0] = planes[:, 0]
    centre = torch.tensor([[[(col + 0.5) / res - 0.5, (row + 0.5) / res - 0.5, 0.0]]]).expand(2, 1, 3)
    torch.testing.assert_close(sample_planes(only_xy, centre, bound)[:, 0], planes[:, 0, :, row, col])


def test_local_pool_gathers_the_cell_means_summed_over_planes():
    torch.manual_seed(1)
    points, feats = torch.rand(1, 30, 3) - 0.5, torch.randn(1, 30, 2)
    index = plane_cell_index(points, 2, 0.5)
    expected = sum(feats[0][index[0, p] == index[0, p, 5]].mean(0) for p in range(3))
    torch.testing.assert_close(local_pool(feats, index, 2)[0, 5], expected)


@pytest.mark.parametrize("res", [4, 8, 32])
def test_unet_and_vae_heads_keep_shapes(res):
    depth = depth_for_resolution(res)
    assert res // 2**depth >= 4
    assert UNet2D(6, 5, 8, depth)(torch.randn(2, 6, res, res)).shape == (2, 5, res, res)
    mu, logvar = PlanePosterior(5, res, 12, 8)(torch.randn(2, 3, 5, res, res))
    assert mu.shape == logvar.shape == (2, 12)
    assert PlaneDecoder(12, res, 5, 8)(mu).shape == (2, 3, 5, res, res)


def test_plane_heads_reject_non_power_of_two():
    with pytest.raises(ValueError, match="power of two"):
        PlanePosterior(4, 12, 8, 8)


def test_gaussian_kl_matches_torch_distributions_for_a_std_prior():
    torch.manual_seed(2)
    mu, logvar = torch.randn(5, 7), torch.randn(5, 7)
    expected = kl_divergence(Normal(mu, torch.exp(0.5 * logvar)), Normal(0.0, 0.25))
    torch.testing.assert_close(gaussian_kl(mu, logvar, prior_std=0.25), expected)
    assert gaussian_kl(torch.zeros(3), torch.full((3,), 2 * torch.log(torch.tensor(0.25))), 0.25).abs().max() < 1e-6


def test_gaussian_kl_matches_a_monte_carlo_estimate():
    gen = torch.Generator().manual_seed(3)
    mu, logvar = torch.tensor([0.3, -0.1]), torch.tensor([-3.0, -2.0])
    h = reparameterize(mu.expand(200_000, 2), logvar.expand(200_000, 2), generator=gen)
    q, p = Normal(mu, torch.exp(0.5 * logvar)), Normal(0.0, 0.25)
    monte_carlo = (q.log_prob(h) - p.log_prob(h)).mean(0)
    torch.testing.assert_close(monte_carlo, gaussian_kl(mu, logvar, 0.25), atol=0.02, rtol=0.02)
