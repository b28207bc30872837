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
    """``mesh`` (in the normalised frame) turned by the 3x3 ``rotation`` about the origin, then scaled
    into the frame of its new heading.

    An object is normalised in the heading it is seen in: turning a long object off its axes widens
    its bounding box (an aircraft's cross narrows it), so the same object normalised in that heading
    is smaller (larger) by the ratio of its longest sides, read here from ``mesh`` itself. The turned
    copy is scaled about the origin, where normalisation put the object's centre and where a
    reconstruction draws it; it is not re-centred on its own box, whose centre a reconstruction that
    misses a wing misplaces (on the validation and test aircraft that cost more than the turn's
    small shift of a true object's box: scripts/placement_variants.py). No turn changes nothing; a quarter turn only turns. A rotation with
    determinant -1 (a mirror) also reverses the faces, so the mesh stays outward.
    """
    rotation = np.asarray(rotation, dtype=np.float64)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    turned = vertices @ rotation.T
    ratio = float(np.ptp(vertices, axis=0).max() / np.ptp(turned, axis=0).max())
    faces = np.asarray(mesh.faces)
    if np.linalg.det(rotation) < 0:
        faces = faces[:, ::-1]
    return trimesh.Trimesh(turned * ratio, np.ascontiguousarray(faces), process=False)
