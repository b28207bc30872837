"""Observation windows (per-axis and cells rules) and noise relative to the response's peak."""

import numpy as np
import pytest

from radar2shape.errors import UserInputError
from radar2shape.radar import add_noise, fixed_window_mask, random_window_mask
from radar2shape.radar.masks import cells_window_size
from radar2shape.radar.signal import noise_power


def _window_lengths(mask: np.ndarray) -> tuple[int, int]:
    """(aspect, roll) lengths of a mask that must be one aspect run x one circular roll run."""
    aspect, roll = mask.any(axis=1), mask.any(axis=0)
    assert np.array_equal(mask, aspect[:, None] & roll[None, :])
    idx = np.flatnonzero(aspect)
    assert idx[-1] - idx[0] + 1 == len(idx)  # aspect never wraps
    if not roll.all():
        assert np.count_nonzero(roll & ~np.roll(roll, 1)) == 1  # one run on the circle
    return int(aspect.sum()), int(roll.sum())


# Hand-worked: 0.3 * 32 * 32 = 307.2 cells; 307 is prime (> 32), 306 = 17 x 18 is 1.2 away and
# 308 = 11 x 28 = 14 x 22 is 0.8 away. 0.3 * 16 * 16 = 76.8: 77 = 7 x 11 (76 = 4 x 19 does not fit).
# 0.5 * 10 * 10 = 50 = 5 x 10.
@pytest.mark.parametrize("n_aspect, n_roll, keep, cells, shapes", [
    (32, 32, 0.3, 308, {(11, 28), (28, 11), (14, 22), (22, 14)}),
    (16, 16, 0.3, 77, {(7, 11), (11, 7)}),
    (10, 10, 0.5, 50, {(5, 10), (10, 5)}),
])
def test_cells_rule_keeps_the_nearest_cell_count(n_aspect, n_roll, keep, cells, shapes):
    seen = set()
    for seed in range(40):
        mask = fixed_window_mask(n_aspect, n_roll, keep, seed=seed, rule="cells")
        assert mask.sum() == cells
        seen.add(_window_lengths(mask))
    assert seen == shapes  # every nearest pair is drawn, nothing else


def test_per_axis_rule_keeps_the_fraction_of_each_axis():
    mask = fixed_window_mask(32, 32, 0.3, seed=3, rule="per_axis")
    assert _window_lengths(mask) == (10, 10) and mask.sum() == 100  # ~9.8 % of the cells
    assert np.array_equal(mask, fixed_window_mask(32, 32, 0.3, seed=3))  # per_axis stays the default


def test_window_size_ties_are_all_drawn():
    # 13 cells on 5 x 7: 13 does not factor within the grid; 12 = 2x6 = 3x4 = 4x3 and 14 = 2x7 are 1 away
    seen = {cells_window_size(5, 7, 13, seed) for seed in range(60)}
    assert seen == {(2, 6), (3, 4), (4, 3), (2, 7)}
    assert cells_window_size(5, 7, 35.0, 0) == (5, 7) and cells_window_size(5, 7, 0.2, 0) == (1, 1)


def test_cells_masks_are_seeded_and_roll_wraps():
    masks = [fixed_window_mask(16, 16, 0.3, seed=s, rule="cells") for s in range(60)]
    assert all(np.array_equal(m, fixed_window_mask(16, 16, 0.3, seed=s, rule="cells")) for s, m in enumerate(masks))
    assert len({m.tobytes() for m in masks}) > 30  # placement and shape vary with the seed
    wrapped = [m for m in masks if m[:, 0].any() and m[:, -1].any() and not m.any(axis=0).all()]
    assert wrapped  # some windows run past 360 deg back to roll 0
    for mask in wrapped:
        _window_lengths(mask)


def test_cells_rule_draws_the_cell_fraction_in_the_training_range():
    rng = np.random.default_rng(0)
    fractions = []
    for _ in range(400):
        mask = random_window_mask(32, 32, 0.3, 1.0, rng, rule="cells")
        _window_lengths(mask)
        fractions.append(mask.mean())
    fractions = np.array(fractions)
    assert fractions.min() >= 0.3 - 1.0 / 1024 and fractions.max() <= 1.0
    # uniform over 308..1024 cells: mean 0.65, std 0.20, so the mean of 400 draws is within 0.01 (1 s.e.)
    assert fractions.mean() == pytest.approx(0.65, abs=0.04)


@pytest.mark.parametrize("low, high", [(0.3, 0.3), (0.3, 1.0)])
def test_one_roll_bin_gives_the_same_mask_under_both_rules(low, high):
    for seed in range(30):
        per_axis = random_window_mask(32, 1, low, high, seed)
        assert np.array_equal(per_axis, random_window_mask(32, 1, low, high, seed, rule="cells"))
    assert fixed_window_mask(32, 1, 0.3, seed=0, rule="cells").sum() == 10  # 0.3 * 32 = 9.6 aspects


def test_bad_rule_is_named():
    with pytest.raises(UserInputError, match="mask_rule.*per_axis, cells.*'square'"):
        fixed_window_mask(8, 8, 0.3, rule="square")


def _response(shape=(64, 64, 32), peak=3.0) -> np.ndarray:
    rng = np.random.default_rng(1)
    response = (rng.normal(size=shape) + 1j * rng.normal(size=shape)).astype(np.complex64) * 0.1
    response[5, 7, 3] = peak  # the peak power is peak**2 = 9 m^2
    return response


@pytest.mark.parametrize("level", [-30.0, -10.0, 0.0])
def test_peak_noise_has_the_requested_power_below_the_peak(level):
    response = _response()
    noise = add_noise(response, level, np.random.default_rng(0), reference="peak").astype(np.complex128) - response
    expected = 9.0 * 10.0 ** (level / 10.0)
    assert noise_power(response, level, "peak") == pytest.approx(expected, rel=1e-6)
    # |n|^2 is exponential (std = mean); over 131,072 cells the mean's relative s.e. is 0.28 %, so 2 %
    # is 7 s.e. (the seed is fixed, the margin only guards the choice of seed)
    assert np.mean(np.abs(noise) ** 2) == pytest.approx(expected, rel=0.02)


def test_peak_noise_scales_with_the_response_and_absolute_does_not():
    response = _response()
    small = add_noise(response, -20.0, 0, reference="peak") - response
    large = add_noise(10.0 * response, -20.0, 0, reference="peak") - 10.0 * response
    np.testing.assert_allclose(large, 10.0 * small, rtol=1e-4, atol=1e-4)  # same draws, 20 dB more power
    assert np.array_equal(add_noise(response, -40.0, 0), add_noise(response, -40.0, 0, reference="absolute"))
    assert noise_power(response, -40.0, "absolute") == pytest.approx(1e-4)
    assert noise_power(np.zeros(4, np.complex64), -10.0, "peak") == 0.0  # nothing to be relative to
    with pytest.raises(UserInputError, match="noise_reference.*'mean'"):
        add_noise(response, -20.0, 0, reference="mean")
