"""The monocone family against closed forms: height, nose sphere, volume; profiles like frusta's."""

import numpy as np
import pytest

from radar2shape.errors import UserInputError
from radar2shape.geometry.families import make_family
from radar2shape.geometry.families.monocone import Monocone
from radar2shape.geometry.profile import profile_to_mesh, validate_profile

CONE = Monocone(base_radius=0.5, half_angle=np.radians(15.0), nose_radius=0.1)


def test_closed_forms_of_a_blunted_cone():
    """Height, tangency and volume from the sharp cone's geometry (not the module's own formulas)."""
    r, a, rn = 0.5, np.radians(15.0), 0.1
    apex = r / np.tan(a)  # sharp cone apex height
    centre = apex - rn / np.sin(a)  # nose centre: distance rn from the cone's side line
    assert CONE.height == pytest.approx(centre + rn, rel=1e-12)
    r_t, z_t = CONE.tangent
    # the tangent point lies on the side line r = (apex - z) tan(a) and on the nose sphere
    assert r_t == pytest.approx((apex - z_t) * np.tan(a), rel=1e-12)
    assert np.hypot(r_t, z_t - centre) == pytest.approx(rn, rel=1e-12)
    # volume = sharp cone - its tip above the tangent plane + the spherical cap above that plane
    cap = centre + rn - z_t
    volume = np.pi / 3 * (r**2 * apex - r_t**2 * (apex - z_t)) + np.pi * cap**2 * (3 * rn - cap) / 3
    assert CONE.volume == pytest.approx(volume, rel=1e-12)
    assert 0.84 < CONE.height / apex < 0.85  # by hand: 0.1 (1 / sin 15 deg - 1) = 0.286 of 1.866, 15 % shorter


def test_mesh_matches_the_closed_forms():
    mesh = profile_to_mesh(CONE.profile(nose_segments=24), segments=256)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.bounds[0, 2] == pytest.approx(0.0, abs=1e-12)
    assert mesh.bounds[1, 2] == pytest.approx(CONE.height, rel=1e-6)  # manifold3d works in float32
    assert mesh.bounds[1, 0] == pytest.approx(0.5, rel=1e-6)
    assert mesh.volume == pytest.approx(CONE.volume, rel=1e-3)  # inscribed polygons: measured 2e-4 low
    assert mesh.volume < CONE.volume
    nose = mesh.vertices[mesh.vertices[:, 2] >= CONE.tangent[1] - 1e-6]
    distance = np.linalg.norm(nose - [0.0, 0.0, CONE.nose_centre_z], axis=1)
    np.testing.assert_allclose(distance, CONE.nose_radius, rtol=1e-5)  # every nose vertex on the sphere


def test_family_profiles_fit_the_frusta_models():
    family = make_family("monocone", {"half_angle_deg": [10, 25], "nose_ratio": [0.1, 0.4]})
    tasks = family.plan(6, {"test": 1.0}, seed=3)
    assert family.roll_symmetric and family.class_names == ["monocone"]
    heights = set()
    for task in tasks:
        shape = family.generate(task)
        cone = family.cone(task.seed)
        validate_profile(shape.profile)
        assert shape.profile.shape == (16, 2)  # frusta's profile_points, so frusta-trained models read it
        assert shape.profile[0].tolist() == [0.0, 0.0] and shape.profile[-1] == pytest.approx([0.0, cone.height])
        assert 10 <= np.degrees(cone.half_angle) <= 25 and 0.1 <= cone.nose_radius / cone.base_radius <= 0.4
        assert shape.mesh.is_watertight and shape.mesh.volume == pytest.approx(cone.volume, rel=0.02)
        assert shape.provenance["nose_radius"] == cone.nose_radius
        heights.add(round(cone.height, 6))
    assert len(heights) == len(tasks)  # sizes are drawn per shape
    np.testing.assert_array_equal(family.generate(tasks[0]).mesh.vertices, family.generate(tasks[0]).mesh.vertices)


def test_fixed_sizes_and_bad_options():
    family = make_family("monocone", {"base_radius": 0.3, "half_angle_deg": 20.0, "nose_ratio": 0.25})
    cone = family.cone(seed=123)
    assert (cone.base_radius, np.degrees(cone.half_angle), cone.nose_radius) == pytest.approx((0.3, 20.0, 0.075))
    with pytest.raises(UserInputError, match="wider than the base"):
        Monocone(base_radius=0.5, half_angle=np.radians(20.0), nose_radius=0.6)
    with pytest.raises(UserInputError, match="exceed profile_points"):
        make_family("monocone", {"nose_segments": 14})
    with pytest.raises(UserInputError, match="low <= high"):
        make_family("monocone", {"nose_ratio": [0.4, 0.1]}).cone(0)
