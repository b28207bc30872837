"""The one shape normalisation used for learning and metrics (docs/design.md section 4).

Bounding-box centre at the origin, longest side 1, so every shape lies in the unit cube
[-0.5, 0.5]^3. The transform is ``x' = (x - centre) * scale``; it is returned so that side data
(profiles, the physical size for the radar) can follow the mesh exactly.
"""

from __future__ import annotations

import numpy as np
import trimesh


def normalisation(vertices: np.ndarray) -> tuple[np.ndarray, float]:
    """``(centre, scale)`` that map ``vertices`` into the unit cube (bbox centre, longest side 1)."""
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    extent = float((hi - lo).max())
    if not np.isfinite(extent) or extent <= 0:
        raise ValueError("cannot normalise a mesh with zero or non-finite extent")
    return (lo + hi) / 2.0, 1.0 / extent


def normalise(mesh: trimesh.Trimesh) -> tuple[trimesh.Trimesh, np.ndarray, float]:
    """A normalised copy of ``mesh`` with the ``(centre, scale)`` that produced it."""
    centre, scale = normalisation(mesh.vertices)
    out = trimesh.Trimesh((np.asarray(mesh.vertices) - centre) * scale, mesh.faces.copy(), process=False)
    return out, centre, scale


def scaled(mesh: trimesh.Trimesh, size: float) -> trimesh.Trimesh:
    """A copy of a normalised mesh at physical size ``size`` (longest side, metres) for the radar."""
    return trimesh.Trimesh(np.asarray(mesh.vertices) * float(size), mesh.faces.copy(), process=False)


def turned_in_frame(mesh: trimesh.Trimesh, rotation: np.ndarray) -> trimesh.Trimesh:
    """``mesh`` (in the normalised frame) turned by the 3x3 ``rotation``, then put back in the frame.

    The frame belongs to the heading the object is seen in: turning a long object off its axes
    widens its bounding box, and the same object normalised in that heading is smaller by the ratio
    of the longest sides. So the turned copy is scaled by that ratio about its bounding-box centre,
    which is moved to where the unturned mesh had its own (a mesh already normalised ends up
    normalised; no turn changes nothing). A rotation with determinant -1 (a mirror) also reverses the
    faces, so the mesh stays outward.
    """
    rotation = np.asarray(rotation, dtype=np.float64)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    before_lo, before_hi = vertices.min(axis=0), vertices.max(axis=0)
    turned = vertices @ rotation.T
    lo, hi = turned.min(axis=0), turned.max(axis=0)
    ratio = float((before_hi - before_lo).max() / (hi - lo).max())
    out = (turned - (lo + hi) / 2.0) * ratio + (before_lo + before_hi) / 2.0
    faces = np.asarray(mesh.faces)
    if np.linalg.det(rotation) < 0:
        faces = faces[:, ::-1]
    return trimesh.Trimesh(out, np.ascontiguousarray(faces), process=False)
