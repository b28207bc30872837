"""scripts/heading_from_radar.py: the heading search finds a turn and mirror from PO responses alone."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import trimesh

from data_modules.augment import turn_and_mirror
from radar2shape.radar import simulate

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("heading_from_radar", REPO / "scripts" / "heading_from_radar.py")
heading = importlib.util.module_from_spec(spec)
spec.loader.exec_module(heading)

ROLL = np.arange(8) * 2 * np.pi / 8


def l_shape() -> trimesh.Trimesh:
    """Two boxes in an L: no mirror plane through z and no turn symmetry, so one turn is right."""
    long = trimesh.creation.box((0.8, 0.15, 0.1), trimesh.transformations.translation_matrix((0.0, 0.0, 0.0)))
    foot = trimesh.creation.box((0.15, 0.35, 0.1), trimesh.transformations.translation_matrix((0.325, 0.25, 0.0)))
    return trimesh.util.concatenate([long, foot])


@pytest.fixture(scope="module")
def response():
    aspect = np.radians(np.linspace(20.0, 160.0, 6))
    return simulate(l_shape(), aspect, ROLL, np.linspace(8e9, 12e9, 4))


@pytest.mark.parametrize("band_average", [False, True])
@pytest.mark.parametrize("turn", [(3, True), (5, False), (0, True)])
def test_the_true_turn_is_found_and_a_level_offset_does_not_matter(response, turn, band_average):
    observed = turn_and_mirror({"radar": response}, *turn, roll_rad=ROLL)["radar"]
    found, scores = heading.estimate_turn(observed, response * 10.0, ROLL, band_average=band_average)  # +20 dB
    assert found == turn
    assert len(scores) == 16 and scores.max() == pytest.approx(1.0, abs=1e-6)  # the same map, shifted
    assert np.sort(scores)[-2] < 0.999  # the L has no symmetric twin among the other turns


def test_db_map_floor_and_correlation_closed_forms():
    power = np.array([1.0, 1e-3, 1e-9])
    np.testing.assert_allclose(heading.db_map(power), [0.0, -30.0, -60.0])  # 1e-9 is 90 dB down: floored at 60
    a = np.array([1.0, 2.0, 3.0])
    assert heading.correlation(a, 2 * a + 5) == pytest.approx(1.0)
    assert heading.correlation(a, -a) == pytest.approx(-1.0)
    assert heading.correlation(a, np.ones(3)) == 0.0
    assert heading.candidate_turns(3) == [(0, False), (1, False), (2, False), (0, True), (1, True), (2, True)]


def test_placed_mesh_is_the_turned_mesh():
    mesh = l_shape()
    arrays = {"vertices": np.asarray(mesh.vertices, np.float32), "faces": np.asarray(mesh.faces)}
    turned = heading.placed(arrays, (2, True), ROLL)  # mirror y -> -y, then a quarter turn about z
    expected = np.asarray(mesh.vertices) * [1.0, -1.0, 1.0]
    expected = expected @ np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # rows: Rz(90) x
    np.testing.assert_allclose(turned.vertices, expected, atol=1e-6)
    assert turned.volume == pytest.approx(mesh.volume, rel=1e-6)  # faces stay outward after the mirror
