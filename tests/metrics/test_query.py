"""geometry.query: sampling, distances and containment against closed forms and trimesh."""

import numpy as np
import pytest
import trimesh

from radar2shape.geometry.query import contains, nearest_distance, sample_surface, unsigned_distance

RNG = np.random.default_rng(0)
UNIFORM = RNG.uniform(-0.55, 0.55, size=(20_000, 3))


def sphere(radius=0.4, subdivisions=4):
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)


def sag(mesh, radius):
    """Largest gap between an icosphere and its sphere (faces are inside the sphere)."""
    return radius - np.linalg.norm(mesh.triangles_center, axis=1).min()


def box_distance(points, half):
    """Exact unsigned distance to the surface of the box [-half, half]."""
    q = np.abs(points) - half
    outside = np.linalg.norm(np.maximum(q, 0), axis=1)
    return np.where(q.max(axis=1) > 0, outside, -q.max(axis=1))


def test_sample_surface_is_area_uniform_and_seeded():
    half = np.array([0.5, 0.25, 0.125])
    box = trimesh.creation.box(extents=2 * half)
    points, normals = sample_surface(box, 40_000, seed=3)
    assert points.shape == normals.shape == (40_000, 3) and points.dtype == normals.dtype == np.float32
    assert np.allclose(box_distance(points, half), 0, atol=1e-6)
    # share of samples on the +-x, +-y, +-z faces = their share of the area (binomial 4 sigma)
    areas = np.array([half[1] * half[2], half[0] * half[2], half[0] * half[1]])
    share = areas / areas.sum()
    counts = np.bincount(np.abs(normals).argmax(axis=1), minlength=3) / len(points)
    assert np.allclose(counts, share, atol=4 * np.sqrt(share * (1 - share) / len(points)))
    assert np.allclose(np.linalg.norm(normals, axis=1), 1, atol=1e-6)
    assert np.array_equal(points, sample_surface(box, 40_000, seed=3)[0])
    assert not np.array_equal(points, sample_surface(box, 40_000, seed=4)[0])


@pytest.mark.parametrize("mesh", [trimesh.Trimesh(), trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])])
def test_sample_surface_of_nothing_is_empty(mesh):
    points, normals = sample_surface(mesh, 100, seed=0)
    assert points.shape == normals.shape == (0, 3)


def test_nearest_distance():
    points = np.array([[0.0, 0, 0], [1, 0, 0]])
    assert np.allclose(nearest_distance([[0.2, 0, 0], [3, 4, 0]], points), [0.2, np.hypot(2, 4)])
    assert np.all(np.isinf(nearest_distance([[0.0, 0, 0]], np.zeros((0, 3)))))


def test_unsigned_distance_box_and_sphere_closed_forms():
    half = np.array([0.3, 0.2, 0.1])
    assert np.allclose(unsigned_distance(trimesh.creation.box(extents=2 * half), UNIFORM), box_distance(UNIFORM, half), atol=1e-12)
    ball = sphere(0.4, 5)
    exact = np.abs(np.linalg.norm(UNIFORM, axis=1) - 0.4)
    assert np.abs(unsigned_distance(ball, UNIFORM) - exact).max() <= sag(ball, 0.4) + 1e-9


def test_unsigned_distance_matches_trimesh_on_random_meshes():
    for seed in range(3):
        rng = np.random.default_rng(seed)
        soup = trimesh.Trimesh(rng.uniform(-0.5, 0.5, (60, 3)), rng.integers(0, 60, (40, 3)), process=False)
        points = rng.uniform(-0.6, 0.6, (300, 3))
        _, reference, _ = trimesh.proximity.closest_point(soup, points)
        assert np.allclose(unsigned_distance(soup, points), reference, atol=1e-9)


def test_unsigned_distance_to_nothing_is_infinite():
    assert np.all(np.isinf(unsigned_distance(trimesh.Trimesh(), UNIFORM[:5])))


def test_contains_sphere_and_box_closed_forms():
    ball = sphere(0.4, 4)
    radius = np.linalg.norm(UNIFORM, axis=1)
    clear = np.abs(radius - 0.4) > sag(ball, 0.4)  # outside the faceting band the answer is known
    assert np.array_equal(contains(ball, UNIFORM)[clear], (radius < 0.4)[clear])
    half = np.array([0.3, 0.2, 0.1])
    assert np.array_equal(contains(trimesh.creation.box(extents=2 * half), UNIFORM), np.all(np.abs(UNIFORM) < half, axis=1))


def test_contains_is_robust_to_holes_flips_and_overlaps():
    ball = sphere(0.4, 4)
    truth = contains(ball, UNIFORM)
    holed = ball.copy()
    keep = np.ones(len(holed.faces), bool)
    keep[np.random.default_rng(1).choice(len(keep), 100, replace=False)] = False  # 2 % of the faces
    holed.update_faces(keep)
    assert not holed.is_watertight
    assert np.count_nonzero(contains(holed, UNIFORM) != truth) <= 0.005 * truth.sum()
    flipped = ball.copy()
    flipped.invert()
    assert np.array_equal(contains(flipped, UNIFORM), truth)
    # two closed boxes overlapping without a boolean union: the overlap is inside (winding 2)
    a, b = np.array([0.3, 0.1, 0.1]), np.array([0.1, 0.3, 0.15])
    cross = trimesh.util.concatenate([trimesh.creation.box(extents=2 * a), trimesh.creation.box(extents=2 * b)])
    expected = np.all(np.abs(UNIFORM) < a, axis=1) | np.all(np.abs(UNIFORM) < b, axis=1)
    assert np.array_equal(contains(cross, UNIFORM), expected)


def test_contains_degenerate_meshes_hold_nothing():
    assert not contains(trimesh.Trimesh(), UNIFORM).any()
    broken = sphere(0.4, 2)
    broken.vertices[0] = np.nan
    assert not contains(broken, UNIFORM).any()
    far = sphere(0.1, 2).apply_translation([10, 0, 0])
    assert not contains(far, UNIFORM).any()


def test_nearest_distance_with_an_upper_bound_is_exact_below_it():
    """The bounded query returns the exact distance within the bound and inf beyond it."""
    rng = np.random.default_rng(0)
    points, query = rng.uniform(-1, 1, (500, 3)), rng.uniform(-1.5, 1.5, (2000, 3))
    exact = nearest_distance(query, points)
    bounded = nearest_distance(query, points, upper_bound=0.1)
    assert np.array_equal(bounded[exact < 0.1], exact[exact < 0.1]) and np.all(np.isinf(bounded[exact > 0.1]))
