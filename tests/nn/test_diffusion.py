"""Schedules against their closed forms, the forward process, and both samplers on exact denoisers."""

import math

import pytest
import torch

from radar2shape.nn.diffusion import GaussianDiffusion, cosine_alpha_bar, linear_betas, spaced_timesteps


def test_cosine_alpha_bar_matches_closed_form():
    diffusion = GaussianDiffusion(num_steps=200, schedule="cosine")
    t = torch.arange(1, 201, dtype=torch.float64) / 200
    expected = torch.cos((t + 0.008) / 1.008 * math.pi / 2) ** 2 / math.cos(0.008 / 1.008 * math.pi / 2) ** 2
    # the last beta is clipped at 0.999 (Nichol & Dhariwal), so compare all but the final step
    torch.testing.assert_close(diffusion.alphas_bar[:-1].double(), expected[:-1], rtol=1e-5, atol=1e-7)
    assert diffusion.betas.max() <= 0.999 + 1e-7
    torch.testing.assert_close(cosine_alpha_bar(torch.tensor(1.0)), torch.tensor(0.0), atol=1e-7, rtol=0)


def test_linear_betas_match_ho_et_al():
    torch.testing.assert_close(linear_betas(1000), torch.linspace(1e-4, 0.02, 1000, dtype=torch.float64))
    diffusion = GaussianDiffusion(num_steps=100, schedule="linear")
    torch.testing.assert_close(diffusion.betas.double(), torch.linspace(1e-3, 0.2, 100, dtype=torch.float64))
    torch.testing.assert_close(diffusion.alphas_bar, torch.cumprod(1 - diffusion.betas, 0))


def test_unknown_schedule_and_bad_steps_raise():
    with pytest.raises(ValueError, match="schedule"):
        GaussianDiffusion(10, schedule="quadratic")
    with pytest.raises(ValueError, match="steps"):
        spaced_timesteps(10, 11)
    assert spaced_timesteps(5, 5) == [4, 3, 2, 1, 0]
    assert spaced_timesteps(1000, 3) == [999, 500, 0]


def test_q_sample_statistics():
    diffusion = GaussianDiffusion(num_steps=100, schedule="linear")
    gen = torch.Generator().manual_seed(0)
    x0 = torch.full((20000, 2), 1.5)
    t = torch.full((20000,), 30)
    xt = diffusion.q_sample(x0, t, torch.randn(x0.shape, generator=gen))
    abar = diffusion.alphas_bar[30]
    assert abs(xt.mean() - abar.sqrt() * 1.5) < 0.02
    assert abs(xt.std() - (1 - abar).sqrt()) < 0.02


@pytest.mark.parametrize("schedule", ["cosine", "linear"])
def test_ddim_all_steps_eta_one_is_ddpm(schedule):
    diffusion = GaussianDiffusion(num_steps=50, schedule=schedule)
    gen = torch.Generator().manual_seed(1)
    x_t, eps = torch.randn(4, 3, 5, generator=gen), torch.randn(4, 3, 5, generator=gen)
    for t in (49, 30, 7, 1, 0):
        ddpm_mean, ddpm_std = diffusion.ddpm_update(x_t, t, eps, variance="posterior")
        ddim_mean, ddim_std = diffusion.ddim_update(x_t, t, t - 1, eps, eta=1.0)
        torch.testing.assert_close(ddim_mean, ddpm_mean, rtol=1e-4, atol=1e-4)
        torch.testing.assert_close(torch.as_tensor(ddim_std), torch.as_tensor(ddpm_std), rtol=1e-4, atol=1e-6)


def gaussian_eps_fn(diffusion, mu, s):
    """Exact E[eps | x_t] when x_0 ~ N(mu, s^2) elementwise."""

    def eps_fn(x, t):
        abar = diffusion.alphas_bar[t].reshape(-1, *([1] * (x.dim() - 1)))
        return (1 - abar).sqrt() * (x - abar.sqrt() * mu) / (abar * s**2 + 1 - abar)

    return eps_fn


@pytest.mark.parametrize("method,steps", [("ddpm", None), ("ddim", 100)])
def test_samplers_reproduce_gaussian_data(method, steps):
    diffusion = GaussianDiffusion(num_steps=100, schedule="cosine")
    gen = torch.Generator().manual_seed(2)
    x = diffusion.sample(gaussian_eps_fn(diffusion, 0.7, 0.3), (4000, 2, 3), method=method, steps=steps, generator=gen)
    assert x.shape == (4000, 2, 3)
    assert abs(x.mean() - 0.7) < 0.02
    assert abs(x.std() - 0.3) < 0.02


def test_few_step_ddim_converges_with_more_steps():
    """Deterministic DDIM under-disperses with few steps (Euler error); the error shrinks with steps."""
    diffusion = GaussianDiffusion(num_steps=100, schedule="cosine")
    eps_fn = gaussian_eps_fn(diffusion, 0.7, 0.3)
    errors = []
    for steps in (10, 20, 50):
        x = diffusion.sample(eps_fn, (8000,), steps=steps, generator=torch.Generator().manual_seed(3))
        assert abs(x.mean() - 0.7) < 0.02
        errors.append(abs(float(x.std()) - 0.3))
    assert errors[0] > errors[1] > errors[2]


def test_ddim_is_deterministic_and_exact_for_a_point_mass():
    diffusion = GaussianDiffusion(num_steps=100, schedule="cosine")
    target = torch.tensor([[0.5, -1.0]])

    def eps_fn(x, t):
        abar = diffusion.alphas_bar[t][:, None]
        return (x - abar.sqrt() * target) / (1 - abar).sqrt()

    a = diffusion.sample(eps_fn, (3, 2), steps=10, generator=torch.Generator().manual_seed(0))
    torch.testing.assert_close(a, target.expand(3, 2), atol=1e-4, rtol=0)


def test_clip_x0_bounds_the_prediction():
    diffusion = GaussianDiffusion(num_steps=10, clip_x0=1.0)
    x0 = diffusion.predict_x0(torch.full((2, 2), 5.0), 9, torch.zeros(2, 2))
    assert x0.abs().max() <= 1.0


def test_velocity_target_is_what_the_skip_turns_into_the_noise():
    """skip_eps(x_t, t, v) = noise and sqrt(abar) x_t - sqrt(1-abar) v = x0 (Salimans & Ho 2022);
    the v-MSE is the noise MSE divided by abar_t (float64: at t = T-1 float32 loses that ratio,
    which is why the model computes the v-loss directly)."""
    diffusion = GaussianDiffusion(100, "cosine")
    gen = torch.Generator().manual_seed(0)
    x0, noise = (torch.randn(6, 3, 5, generator=gen, dtype=torch.float64) for _ in range(2))
    t = torch.tensor([0, 10, 40, 70, 95, 99])
    x_t = diffusion.q_sample(x0, t, noise)
    v = diffusion.v_target(x0, t, noise)
    torch.testing.assert_close(diffusion.skip_eps(x_t, t, v), noise, atol=1e-5, rtol=0)
    abar = diffusion.alphas_bar[t][:, None, None]
    torch.testing.assert_close(abar.sqrt() * x_t - (1 - abar).sqrt() * v, x0, atol=1e-5, rtol=0)
    error = torch.randn(6, 3, 5, generator=gen, dtype=torch.float64)
    eps_error = diffusion.skip_eps(x_t, t, v + error) - noise
    torch.testing.assert_close(eps_error.pow(2) / abar, error.pow(2), atol=1e-8, rtol=1e-6)


def test_guidance_combines_the_two_predictions_and_scale_one_is_conditional():
    from radar2shape.nn.diffusion import guided

    calls = []
    cond = lambda x, t: calls.append("c") or torch.full_like(x, 2.0)  # noqa: E731
    uncond = lambda x, t: calls.append("u") or torch.full_like(x, 0.5)  # noqa: E731
    x, t = torch.zeros(3, 2), torch.zeros(3, dtype=torch.long)
    assert guided(cond, uncond, 1.0) is cond  # no unconditional pass at scale 1
    torch.testing.assert_close(guided(cond, uncond, 3.0)(x, t), torch.full((3, 2), 0.5 + 3.0 * 1.5))
    torch.testing.assert_close(guided(cond, uncond, 0.0)(x, t), torch.full((3, 2), 0.5))  # the prior alone
    assert calls == ["u", "c", "u", "c"]


def test_condition_dropout_blanks_whole_samples_at_the_asked_rate():
    from radar2shape.nn.diffusion import drop_condition

    radar, mask = torch.randn(4000, 3, 5), torch.rand(4000, 3) < 0.8
    assert drop_condition(radar, mask, 0.0) == (radar, mask)
    before = radar.clone()
    dropped, kept = drop_condition(radar, mask, 0.25, torch.Generator().manual_seed(0))
    blank = (dropped == 0).flatten(1).all(dim=1)  # a Gaussian radar row is never all zero
    assert 0.22 < blank.float().mean() < 0.28  # 1000 expected of 4000 (std 27)
    assert not kept[blank].any() and torch.equal(dropped[~blank], radar[~blank]) and torch.equal(kept[~blank], mask[~blank])
    assert torch.equal(radar, before)  # inputs untouched
    dropped, kept = drop_condition(radar, mask, 1.0)
    assert not kept.any() and not dropped.any()
