"""Profiles of roll-symmetric shapes: validation, resampling and the mesh round trip."""

import numpy as np
import pytest

from radar2shape.errors import UserInputError
from radar2shape.geometry.families.frusta import random_profile
from radar2shape.geometry.profile import (
    canonical_profile,
    mesh_to_profile,
    profile_to_mesh,
    resample_profile,
    validate_profile,
)


@pytest.mark.parametrize(
    "profile, message",
    [
        ([[0.2, 0.0]], "at least two"),
        ([[0.2, 0.0], [-0.1, 1.0]], ">= 0"),
        ([[0.2, 1.0], [0.3, 0.5]], "non-decreasing"),
        ([[0.2, 0.0], [0.3, 0.0]], "no volume"),
        ([[0.2, 0.0], [0.0, 0.5], [0.2, 1.0]], "axis"),
        ([[0.2, 0.0, 1.0]], "shape"),
        ([[0.2, np.nan], [0.3, 1.0]], "NaN"),
    ],
)
def test_bad_profiles_raise_clear_errors(profile, message):
    with pytest.raises(UserInputError, match=message):
        validate_profile(profile)


def test_canonical_profile_closes_on_the_axis_and_drops_collinear_points():
    profile = canonical_profile([[0.3, 0.0], [0.3, 0.5], [0.3, 1.0], [0.1, 2.0]])
    np.testing.assert_allclose(profile, [[0, 0], [0.3, 0], [0.3, 1.0], [0.1, 2.0], [0, 2.0]])


def test_resampling_keeps_every_corner_and_the_count():
    corners = canonical_profile(random_profile(np.random.default_rng(3), 5))
    resampled = resample_profile(corners, 16)
    assert resampled.shape == (16, 2)
    assert all(np.isclose(resampled, c).all(axis=1).any() for c in corners)
    np.testing.assert_allclose(canonical_profile(resampled), corners, atol=1e-12)
    with pytest.raises(UserInputError, match="corners"):
        resample_profile(corners, len(corners) - 1)


@pytest.mark.parametrize("seed", range(8))
def test_profile_mesh_round_trip(seed):
    rng = np.random.default_rng(seed)
    profile = random_profile(rng, int(rng.integers(1, 6)), step_probability=0.5, point_probability=0.5)
    mesh = profile_to_mesh(profile, segments=48)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    np.testing.assert_allclose(mesh_to_profile(mesh, 16), resample_profile(profile, 16), atol=1e-6)


def test_revolved_volume_matches_the_frustum_formula():
    r0, r1, h = 0.3, 0.1, 1.0
    mesh = profile_to_mesh([[r0, 0.0], [r1, h]], segments=256)
    exact = np.pi * h * (r0**2 + r0 * r1 + r1**2) / 3
    assert mesh.volume == pytest.approx(exact, rel=1e-3)


def test_mesh_to_profile_rejects_meshes_that_are_not_one_solid_of_revolution():
    import trimesh

    two = trimesh.util.concatenate([trimesh.creation.box(bounds=[[-1, -1, 0], [1, 1, 1]]),
                                    trimesh.creation.box(bounds=[[-1, -1, 2], [1, 1, 3]])])
    with pytest.raises(UserInputError, match="outlines"):
        mesh_to_profile(two)
