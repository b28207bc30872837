"""geometry.marching_cubes: radius, orientation, closing at the boundary, empty and NaN grids."""

import numpy as np
import pytest
import torch

from radar2shape.geometry.marching_cubes import extract_mesh, grid_points, sdf_grid_to_mesh


def sphere_sdf(resolution, radius, centre=(0.0, 0.0, 0.0), bounds=(-0.5, 0.5)):
    points = grid_points(resolution, bounds).reshape((resolution,) * 3 + (3,))
    return np.linalg.norm(points - np.asarray(centre), axis=-1) - radius


@pytest.mark.parametrize("bounds, centre", [((-0.5, 0.5), (0.0, 0.0, 0.0)), ((-1.0, 0.25), (-0.4, 0.05, -0.1))])
def test_sphere_has_the_right_radius_and_outward_normals(bounds, centre):
    centre = np.asarray(centre)
    mesh = sdf_grid_to_mesh(sphere_sdf(48, 0.2, centre, bounds), bounds)
    radii = np.linalg.norm(mesh.vertices - centre, axis=1)
    spacing = (bounds[1] - bounds[0]) / 47
    assert abs(radii.mean() - 0.2) < 0.02 * spacing  # vertices are linear interpolations of an exact SDF
    assert np.abs(radii - 0.2).max() < 0.1 * spacing
    assert mesh.is_watertight and mesh.volume > 0  # positive volume <=> outward normals
    assert np.all(np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles_center - centre) > 0)


def test_surface_cut_by_the_grid_is_capped_at_the_boundary():
    points = grid_points(32).reshape(32, 32, 32, 3)
    cube = np.abs(points).max(axis=-1) - 0.7  # larger than the grid: everything inside
    mesh = sdf_grid_to_mesh(cube)
    assert mesh.is_watertight and mesh.volume > 0
    assert np.allclose(mesh.bounds, [[-0.5] * 3, [0.5] * 3], atol=1e-3 / 31)


def test_no_zero_crossing_or_all_nan_is_empty():
    assert len(sdf_grid_to_mesh(np.ones((8, 8, 8))).faces) == 0
    assert len(sdf_grid_to_mesh(np.full((8, 8, 8), np.nan)).faces) == 0


def test_nan_counts_as_outside():
    sdf = sphere_sdf(32, 0.3)
    clean = sdf_grid_to_mesh(sdf)
    sdf[0, 0, 0] = sdf[31, 5, 7] = np.nan  # far from the surface
    assert np.isclose(sdf_grid_to_mesh(sdf).volume, clean.volume)


def test_rejects_non_cubic_grids():
    with pytest.raises(ValueError, match="cubic"):
        sdf_grid_to_mesh(np.zeros((4, 4, 5)))


def test_extract_mesh_evaluates_in_chunks_and_matches_the_grid_path():
    calls = []

    def sdf_fn(points: torch.Tensor) -> torch.Tensor:
        calls.append(len(points))
        assert not torch.is_grad_enabled()
        return (points.norm(dim=-1) - 0.3).unsqueeze(-1)  # [M, 1] is accepted

    mesh = extract_mesh(sdf_fn, resolution=24, batch_points=5000, narrow_band=False)
    assert max(calls) == 5000 and sum(calls) == 24**3
    reference = sdf_grid_to_mesh(sphere_sdf(24, 0.3))
    assert np.allclose(mesh.vertices, reference.vertices, atol=1e-6)


def _box(points: torch.Tensor, half=(0.3, 0.02, 0.2)) -> torch.Tensor:
    q = points.abs() - torch.tensor(half, dtype=points.dtype)
    return q.clamp(min=0).norm(dim=1) + q.max(dim=1).values.clamp(max=0)


def _spheres(points: torch.Tensor) -> torch.Tensor:
    centres = torch.tensor([[0.1, 0.1, 0.0], [-0.2, 0.0, 0.1], [0.25, -0.3, -0.2], [0.45, 0.45, 0.45]])
    radii = torch.tensor([0.2, 0.1, 0.05, 0.12])  # the last one is cut by the grid: capped
    return ((points[:, None] - centres[None]).norm(dim=2) - radii).min(dim=1).values


def _with_nan(points: torch.Tensor) -> torch.Tensor:
    values = _spheres(points)
    return torch.where(points[:, 0] > 0.3, torch.full_like(values, float("nan")), values)


@pytest.mark.parametrize("sdf_fn", [_box, _spheres, _with_nan], ids=["thin plate", "spheres", "nan region"])
@pytest.mark.parametrize("resolution", [33, 64])
def test_narrow_band_gives_the_full_grid_mesh_for_a_fraction_of_the_queries(sdf_fn, resolution):
    """Only blocks near the surface are refined: the same vertices and faces as evaluating every
    grid point (a 0.04-thick plate, spheres one of which the grid cuts, a NaN half-space)."""
    count = []

    def counted(points):
        count.append(len(points))
        return sdf_fn(points)

    full = extract_mesh(sdf_fn, resolution, narrow_band=False)
    band = extract_mesh(counted, resolution)
    assert len(full.faces) > 100 and np.array_equal(full.faces, band.faces)
    assert np.abs(full.vertices - band.vertices).max() < 1e-3 / (resolution - 1)  # caps: 1e-3 cell
    # measured: 15-21 % of the points at 64^3, 52 % at 33^3; NaN points are always evaluated
    limit = {33: 0.6, 64: 0.3}[resolution] + (0.15 if sdf_fn is _with_nan else 0.0)
    assert sum(count) < limit * resolution**3


def test_narrow_band_trusts_a_truncated_sdf_only_up_to_its_truncation():
    """A model trained with a loss truncated at t only knows the sign beyond it; here (t = 0.05)
    the far field overshoots twentyfold. A sphere of radius 0.03 in the middle of a coarse block is
    then invisible from the block's corners (0.08 from its surface), unless the band is told where
    the SDF stops being a distance."""
    centre = torch.full((3,), -0.5 + 4.0 / 63)  # the middle of the first 8-cell block

    def overshooting(points):
        d = (points - centre).norm(dim=1) - 0.03
        return torch.where(d.abs() < 0.05, d, torch.sign(d) * (0.05 + 20 * (d.abs() - 0.05)))

    full = extract_mesh(overshooting, 64, narrow_band=False)
    assert len(full.faces) > 50
    assert len(extract_mesh(overshooting, 64).faces) == 0  # trusting the far field loses it
    limited = extract_mesh(overshooting, 64, distance_limit=0.05)
    assert np.array_equal(full.faces, limited.faces) and np.allclose(full.vertices, limited.vertices)
