"""Radial profiles of roll-symmetric shapes and their conversion to and from meshes.

A profile is the outline of the half cross-section, a polyline of ``(r, z)`` points from bottom
to top: ``r >= 0`` and ``z`` non-decreasing (equal ``z`` = a flat step or cap). Revolving it about
the z axis gives the solid, so roll about z is the symmetry. The *canonical* form starts and
ends on the axis (``r = 0``): a first point with ``r > 0`` means a flat bottom cap, a first
point on the axis a pointed end. For learning, profiles are resampled to a fixed number of
points ``P`` that always contains every corner (extra points are spread over the longest
segments), so resampling never changes the shape.
"""

from __future__ import annotations

import manifold3d
import numpy as np
import trimesh

from radar2shape.errors import UserInputError
from radar2shape.geometry.manifold import to_trimesh

_EPS = 1e-9


def validate_profile(profile, name: str = "profile") -> np.ndarray:
    """``profile`` as float64 ``[n, 2]`` after checking it describes a solid of revolution."""
    points = np.asarray(profile, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise UserInputError(f"{name}: expected an array of (r, z) points with shape [n, 2], got {points.shape}")
    if len(points) < 2:
        raise UserInputError(f"{name}: needs at least two (r, z) points, got {len(points)}")
    if not np.isfinite(points).all():
        raise UserInputError(f"{name}: contains NaN or infinite values")
    r, z = points.T
    if (r < 0).any():
        raise UserInputError(f"{name}: radii must be >= 0 (point {int(np.argmax(r < 0))} has r = {r.min():g})")
    if (np.diff(z) < 0).any():
        raise UserInputError(f"{name}: z must be non-decreasing from bottom to top (point {int(np.argmax(np.diff(z) < 0)) + 1})")
    if z[-1] - z[0] <= _EPS or r.max() <= _EPS:
        raise UserInputError(f"{name}: encloses no volume (height {z[-1] - z[0]:g}, largest radius {r.max():g})")
    if (r[1:-1] <= _EPS).any():
        raise UserInputError(f"{name}: only the first and last point may lie on the axis (r = 0)")
    return points


def canonical_profile(profile) -> np.ndarray:
    """Validated profile closed onto the axis at both ends, without repeated or collinear points."""
    points = validate_profile(profile)
    if points[0, 0] > _EPS:
        points = np.vstack([[0.0, points[0, 1]], points])
    if points[-1, 0] > _EPS:
        points = np.vstack([points, [0.0, points[-1, 1]]])
    points[[0, -1], 0] = 0.0
    return _drop_collinear(points)


def _drop_collinear(points: np.ndarray, tol: float = 1e-7) -> np.ndarray:
    """Remove repeated points and interior points lying on the segment between their neighbours."""
    keep = np.r_[True, np.linalg.norm(np.diff(points, axis=0), axis=1) > tol]
    points = points[keep]
    while len(points) > 2:
        before, here, after = points[:-2], points[1:-1], points[2:]
        d1, d2 = here - before, after - here
        cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
        straight = (np.abs(cross) <= tol * np.linalg.norm(d1, axis=1) * np.linalg.norm(d2, axis=1)) & (
            np.einsum("ij,ij->i", d1, d2) > 0
        )
        if not straight.any():
            break
        points = np.delete(points, 1 + np.flatnonzero(straight)[:1], axis=0)
    return points


def resample_profile(profile, n_points: int) -> np.ndarray:
    """The canonical profile with exactly ``n_points`` points, every corner kept.

    The ``n_points - corners`` extra points go to segments in proportion to their length
    (largest-remainder rounding), each segment split evenly; deterministic, so equal shapes give
    equal arrays.
    """
    corners = canonical_profile(profile)
    extra = n_points - len(corners)
    if extra < 0:
        raise UserInputError(f"profile has {len(corners)} corners, more than the {n_points} profile points allowed")
    length = np.linalg.norm(np.diff(corners, axis=0), axis=1)
    share = extra * length / length.sum()
    count = np.floor(share).astype(int)
    count[np.argsort(count - share)[: extra - count.sum()]] += 1
    pieces = [
        start + np.linspace(0.0, 1.0, k + 1, endpoint=False)[:, None] * (end - start)
        for start, end, k in zip(corners[:-1], corners[1:], count)
    ]
    return np.vstack(pieces + [corners[-1:]])


def profile_to_mesh(profile, segments: int = 64) -> trimesh.Trimesh:
    """Watertight mesh of the solid of revolution about z (``segments`` sectors, one at angle 0).

    ``segments`` is rounded up to a multiple of 4 so the mesh's bounding box is the ideal
    solid's, which keeps the normalisation of mesh and profile identical.
    """
    corners = canonical_profile(profile)
    segments = int(4 * np.ceil(segments / 4))
    section = manifold3d.CrossSection([corners.astype(np.float64)])  # CCW in the (r, z) plane
    return to_trimesh(section.revolve(circular_segments=segments))


def mesh_to_profile(mesh: trimesh.Trimesh, n_points: int | None = None) -> np.ndarray:
    """The profile of a mesh symmetric about z: its section by the half-plane y = 0, x >= 0.

    Returns the canonical profile, or exactly ``n_points`` points when given. Raises
    ``UserInputError`` when the section is not a single outline (the mesh is not one solid of
    revolution about z).
    """
    section = mesh.section(plane_origin=np.zeros(3), plane_normal=np.array([0.0, 1.0, 0.0]))
    if section is None:
        raise UserInputError("mesh_to_profile: the mesh does not cross the plane y = 0")
    loops = section.discrete
    if len(loops) != 1:
        raise UserInputError(f"mesh_to_profile: the section y = 0 has {len(loops)} outlines, expected 1")
    loop = np.asarray(loops[0])[:, [0, 2]]  # (x, z)
    if np.allclose(loop[0], loop[-1]):
        loop = loop[:-1]
    half = _half_outline(loop)
    profile = canonical_profile(half)
    return profile if n_points is None else resample_profile(profile, n_points)


def _half_outline(loop: np.ndarray) -> np.ndarray:
    """The x >= 0 part of a closed outline symmetric in x, as (r, z) from bottom to top."""
    scale = max(float(np.ptp(loop, axis=0).max()), _EPS)
    on_axis = np.abs(loop[:, 0]) <= 1e-6 * scale
    axis_points = np.flatnonzero(on_axis)
    if len(axis_points) < 2:
        raise UserInputError("mesh_to_profile: the section does not meet the z axis twice")
    start = axis_points[np.argmin(loop[axis_points, 1])]
    ring = np.roll(loop, -start, axis=0)
    if ring[1, 0] < 0:  # walk towards x > 0
        ring = np.vstack([ring[:1], ring[1:][::-1]])
    top = 1 + np.flatnonzero(np.abs(ring[1:, 0]) <= 1e-6 * scale)[0]
    half = ring[: top + 1].copy()
    half[:, 0] = np.abs(half[:, 0])
    return half
