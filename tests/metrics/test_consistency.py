"""Radar consistency: hand-computed residuals, and a shape that explains its radar better than another."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from radar2shape.metrics.consistency import power_residual, radar_consistency
from radar2shape.radar import RadarGrid, simulate, to_db
from radar2shape.radar.spec import RadarSpec


def db(power) -> np.ndarray:
    return 10 * np.log10(np.asarray(power, dtype=float)).reshape(1, 1, -1)


def test_power_residual_hand_values():
    mask = np.ones((1, 1), dtype=bool)
    assert power_residual(db([3.0, 6.0]), np.array([1.0, 2.0]).reshape(1, 1, 2), mask) == pytest.approx(0.0, abs=1e-12)
    assert power_residual(db([1.0, 1.0]), np.array([1.0, 0.0]).reshape(1, 1, 2), mask) == pytest.approx(1 / np.sqrt(2))
    assert power_residual(db([1.0, 1e-30]), np.array([0.0, 1.0]).reshape(1, 1, 2), mask) == pytest.approx(1.0)
    observed = db([1.0, 4.0]).repeat(2, axis=1)  # two roll cells; the second is masked and differs
    observed[0, 1] = db([100.0, 1.0])
    simulated = np.array([1.0, 4.0]).reshape(1, 1, 2).repeat(2, axis=1)
    assert power_residual(observed, simulated, np.array([[True, False]])) == pytest.approx(0.0, abs=1e-12)
    nan_cell = observed.copy()
    nan_cell[0, 0, 1] = np.nan  # a frequency without data is left out, not counted as zero power
    assert power_residual(nan_cell, simulated, np.array([[True, False]])) == pytest.approx(0.0, abs=1e-12)


def test_the_true_shape_explains_its_radar_better_than_another():
    grid = RadarGrid(np.linspace(0.2, np.pi - 0.2, 6), np.linspace(0, 2 * np.pi, 6, endpoint=False),
                     np.linspace(8e9, 12e9, 4), 1.0)
    spec = RadarSpec(grid, -20.0, 10.0)
    box = trimesh.creation.box(extents=(1.0, 0.6, 0.3))
    observed = to_db(simulate(box, grid.aspect_rad, grid.roll_rad, grid.freq_hz))
    mask = np.ones(observed.shape[:2], dtype=bool)
    own = radar_consistency(box, observed, mask, spec)
    sphere = radar_consistency(trimesh.creation.icosphere(3, radius=0.5), observed, mask, spec)
    assert own < 1e-3 < sphere
