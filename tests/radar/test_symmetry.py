"""Roll symmetry of the simulator, and the exact augmentation built on it (data_modules/augment.py).

On a non-symmetric solid simulated on R rolls covering [0, 2 pi): the solid turned about z by k
roll steps gives ``np.roll`` of the response by k along roll, and the solid mirrored through the xz
plane (y -> -y, faces reversed to stay outward) gives the roll-reversed response (index r -> -r mod
R). Both hold to float precision: the largest difference is below 1e-5 of the peak |S| in
complex128 (the geometry is turned in float64; what is left is rounding in the facet integrals
and in Embree's float32 shadow rays).
"""

import numpy as np
import pytest
import trimesh

from data_modules.augment import turn_and_mirror
from radar2shape.geometry import query
from radar2shape.geometry.manifold import from_trimesh, to_trimesh, union_all
from radar2shape.radar import simulate

ROLLS = 12
ROLL = 2 * np.pi * np.arange(ROLLS) / ROLLS
ASPECT = np.linspace(0.2, np.pi - 0.2, 7)
FREQ = np.linspace(2e9, 4e9, 5)
TOLERANCE = 1e-5  # of the peak |S|


def irregular_solid() -> trimesh.Trimesh:
    """A box with an off-centre bump and a tilted wedge: no mirror plane, no rotation axis."""
    box = trimesh.creation.box((0.4, 0.25, 0.15))
    bump = trimesh.creation.box((0.1, 0.08, 0.1))
    bump.apply_translation((0.12, 0.07, 0.11))
    wedge = trimesh.Trimesh([[-0.2, -0.12, 0.075], [-0.05, -0.12, 0.075], [-0.2, 0.02, 0.075], [-0.17, -0.1, 0.2]],
                            [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    return to_trimesh(union_all([from_trimesh(part) for part in (box, bump, wedge)]))  # one closed solid


def turned(mesh, steps):
    angle = 2 * np.pi * steps / ROLLS
    matrix = trimesh.transformations.rotation_matrix(angle, [0, 0, 1])
    return trimesh.Trimesh(trimesh.transform_points(mesh.vertices, matrix), mesh.faces, process=False)


def mirrored(mesh):
    return trimesh.Trimesh(mesh.vertices * [1, -1, 1], mesh.faces[:, ::-1], process=False)


def response(mesh):
    return simulate(mesh, ASPECT, ROLL, FREQ, dtype=np.complex128)


@pytest.fixture(scope="module")
def original():
    return response(irregular_solid())


def assert_close(actual, expected):
    peak = np.abs(expected).max()
    assert np.abs(actual - expected).max() <= TOLERANCE * peak


def test_the_solid_has_no_roll_symmetry_to_hide_errors(original):
    peak = np.abs(original).max()
    for steps in range(1, ROLLS):
        assert np.abs(np.roll(original, steps, axis=1) - original).max() > 0.05 * peak
    assert np.abs(original[:, (-np.arange(ROLLS)) % ROLLS] - original).max() > 0.05 * peak


@pytest.mark.parametrize("steps", [1, 5])
def test_turning_about_z_shifts_the_response_along_roll(original, steps):
    assert_close(response(turned(irregular_solid(), steps)), np.roll(original, steps, axis=1))


def test_mirroring_through_xz_reverses_roll(original):
    assert_close(response(mirrored(irregular_solid())), original[:, (-np.arange(ROLLS)) % ROLLS])


@pytest.mark.parametrize("shift, mirror", [(3, False), (0, True), (7, True)])
def test_turn_and_mirror_matches_the_transformed_solid(original, shift, mirror):
    mesh = irregular_solid()
    rng = np.random.default_rng(0)
    occ = rng.uniform(-0.3, 0.3, size=(4000, 3))
    surface, normals = query.sample_surface(mesh, 500, rng)
    sample = {"radar": original, "roll_rad": ROLL, "occ_points": occ, "occ_inside": query.contains(mesh, occ),
              "surface_points": surface, "surface_normals": normals, "sdf_values": np.zeros(3, np.float32),
              "vertices": np.asarray(mesh.vertices), "faces": np.asarray(mesh.faces)}
    out = turn_and_mirror(sample, shift, mirror)
    moved = mirrored(mesh) if mirror else mesh
    moved = turned(moved, shift)
    assert_close(out["radar"], response(moved))  # the radar re-indexed = the transformed solid simulated
    assert np.allclose(out["vertices"], moved.vertices, atol=1e-12)
    assert np.array_equal(out["faces"], moved.faces)
    assert np.array_equal(query.contains(moved, out["occ_points"]), sample["occ_inside"])  # labels still hold
    assert query.unsigned_distance(moved, out["surface_points"]).max() < 1e-6  # on the surface (float32 points)
    closest, _, triangle = trimesh.proximity.closest_point(moved, out["surface_points"])
    assert (np.einsum("ij,ij->i", out["surface_normals"], moved.face_normals[triangle]) > 0.999).mean() > 0.98
    assert out["sdf_values"] is sample["sdf_values"]


def test_turn_and_mirror_refuses_a_partial_roll_axis():
    with pytest.raises(ValueError, match="full circle|equal steps"):
        turn_and_mirror({"radar": np.zeros((2, 3, 1)), "roll_rad": np.array([0.0, 0.1, 0.2])}, 1, False)
