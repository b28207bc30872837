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
