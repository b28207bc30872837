"""Validated, precomputed facet data that the PO kernel and the shadow rays share.

Everything is float64 and relative to a local origin (the bounding-box centre), so that phases
2k u.r stay small enough for float32 later on; the simulator puts the origin's phase back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.spatial

from radar2shape.errors import UserInputError

# A face whose area is below this fraction of the squared bbox diagonal carries no PO current
# (zero area) but would give NaN normals: it is dropped (the documented repair).
DEGENERATE_AREA = 1e-12
# Shadow rays start this fraction of the bbox diagonal above the facet centroid (float32 safe).
RAY_OFFSET = 1e-5


@dataclass(frozen=True)
class FacetMesh:
    """Triangles ready for PO: geometry per facet and the vertex incidence for phase sums."""

    origin: np.ndarray  # [3] local origin (bbox centre) in the input's coordinates
    vertices: np.ndarray  # [V, 3] relative to origin, only referenced vertices
    faces: np.ndarray  # [F, 3] int64, counter-clockwise about the normal
    normals: np.ndarray  # [F, 3] unit outward normals
    areas: np.ndarray  # [F]
    centroids: np.ndarray  # [F, 3]
    edges: np.ndarray  # [F, 3, 3] e_m = r_{m+1} - r_m
    midpoints: np.ndarray  # [F, 3, 3] edge midpoints
    gather: scipy.sparse.csr_array  # [V, 3F]: sums per-corner values (corner i of face f at i*F + f) per vertex
    supported: np.ndarray  # [F] bool: plane supports the whole mesh, so never occluded when lit
    ray_origins: np.ndarray  # [F, 3] float32 centroid + offset * normal
    n_dropped: int  # degenerate faces removed

    @property
    def n_faces(self) -> int:
        return len(self.faces)


def _arrays(mesh) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) from a trimesh-like object or a (vertices, faces) pair."""
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        vertices, faces = mesh.vertices, mesh.faces
    elif isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        vertices, faces = mesh
    else:
        raise UserInputError(f"mesh: expected a trimesh.Trimesh or a (vertices, faces) pair, got {type(mesh).__name__}")
    try:
        vertices = np.asarray(vertices, dtype=np.float64)
        faces = np.asarray(faces)
    except (TypeError, ValueError) as err:
        raise UserInputError(f"mesh: vertices/faces are not numeric arrays ({err})") from err
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise UserInputError(f"mesh: vertices must have shape [V, 3], got {vertices.shape}")
    if faces.size == 0 or len(vertices) == 0:
        raise UserInputError("mesh: is empty (no vertices or no faces)")
    if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
        raise UserInputError(f"mesh: faces must be integer triangles [F, 3], got {faces.dtype} {faces.shape}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise UserInputError(f"mesh: face indices must lie in [0, {len(vertices) - 1}]")
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise UserInputError(f"mesh: {int(bad.sum())} vertices are NaN or infinite")
    return vertices, faces.astype(np.int64)


def _supported(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray, centroids: np.ndarray,
               tol: float) -> np.ndarray:
    """Facets whose plane has the whole mesh behind it (within tol): no ray from them is blocked.

    Such a plane is a convex-hull facet plane through the facet's first vertex, so only the
    hull facets around that vertex are tried: tilt |n_f - n_h| times the hull size plus the
    facet centroid's distance to the hull plane must stay within tol.
    """
    try:
        hull = scipy.spatial.ConvexHull(vertices)
    except scipy.spatial.QhullError:  # flat mesh: every vertex lies in the facets' plane
        return np.array([np.abs(vertices @ n - n @ c).max() <= tol for n, c in zip(normals, centroids)])
    plane_n, plane_d = hull.equations[:, :3], hull.equations[:, 3]
    around = scipy.sparse.csr_array(  # vertex -> hull facets touching it
        (np.ones(hull.simplices.size), (hull.simplices.ravel(), np.repeat(np.arange(len(hull.simplices)), 3))),
        shape=(len(vertices), len(hull.simplices)))
    counts = np.diff(around.indptr)[faces[:, 0]]
    face = np.repeat(np.arange(len(faces)), counts)
    starts = around.indptr[faces[:, 0]]
    h = around.indices[np.repeat(starts - np.cumsum(counts) + counts, counts) + np.arange(counts.sum())]
    size = np.ptp(vertices, axis=0).max()
    slack = np.linalg.norm(normals[face] - plane_n[h], axis=1) * size
    slack += np.abs(np.einsum("ij,ij->i", centroids[face], plane_n[h]) + plane_d[h])
    supported = np.zeros(len(faces), dtype=bool)
    supported[face[slack <= tol]] = True
    return supported


def facet_mesh(mesh) -> FacetMesh:
    """Validate ``mesh`` and precompute its facets; drops degenerate (zero-area) faces."""
    vertices, faces = _arrays(mesh)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    origin = (lo + hi) / 2.0
    diag = float(np.linalg.norm(hi - lo))
    tri = vertices[faces] - origin
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    keep = double_area > 2 * DEGENERATE_AREA * diag**2
    if not keep.any():
        raise UserInputError("mesh: every face is degenerate (zero area)")
    faces, tri, cross, double_area = faces[keep], tri[keep], cross[keep], double_area[keep]

    used, faces = np.unique(faces, return_inverse=True)
    faces = faces.reshape(-1, 3)
    local = vertices[used] - origin
    normals = cross / double_area[:, None]
    centroids = tri.mean(axis=1)
    edges = np.roll(tri, -1, axis=1) - tri
    midpoints = (np.roll(tri, -1, axis=1) + tri) / 2.0
    corners = np.arange(3 * len(faces))
    gather = scipy.sparse.csr_array((np.ones(len(corners)), (faces.T.ravel(), corners)), shape=(len(local), len(corners)))
    offset = RAY_OFFSET * diag
    return FacetMesh(
        origin=origin,
        vertices=local,
        faces=faces,
        normals=normals,
        areas=double_area / 2.0,
        centroids=centroids,
        edges=edges,
        midpoints=midpoints,
        gather=gather,
        supported=_supported(local, faces, normals, centroids, 0.5 * offset),
        ray_origins=(centroids + offset * normals).astype(np.float32),
        n_dropped=int((~keep).sum()),
    )
