"""Reducing a watertight mesh to a face budget while keeping it watertight.

Backend: manifold3d's edge-collapse simplification (``Manifold.simplify(tolerance)``), which
moves the surface by less than ``tolerance`` and always returns a manifold. trimesh's quadric
decimation would hit the budget exactly but needs the optional ``fast_simplification`` package
and may open the surface, so it is not used. The budget is met by growing the tolerance.
"""

from __future__ import annotations

import numpy as np
import trimesh

from radar2shape.geometry.manifold import from_trimesh, to_trimesh

_START_TOLERANCE = 1e-4  # first tolerance, as a fraction of the longest side
_GROWTH = 1.5  # tolerance growth per pass


def simplify(mesh: trimesh.Trimesh, max_faces: int) -> trimesh.Trimesh:
    """``mesh`` with at most ``max_faces`` faces (typically 0.7-1x the budget).

    Progressive: each pass simplifies the previous result with a 1.5x larger tolerance, so
    the expensive first passes run on the big mesh only once and the total surface movement
    stays below ~3x the last tolerance. The input must be watertight (``geometry.repair``); a
    mesh within budget is returned unchanged.
    """
    if len(mesh.faces) <= max_faces:
        return mesh
    solid = from_trimesh(mesh)
    size = float(np.ptp(mesh.vertices, axis=0).max())
    tolerance = _START_TOLERANCE * size
    while solid.num_tri() > max_faces:
        if tolerance > size:
            raise ValueError(f"cannot simplify below {solid.num_tri()} faces (budget {max_faces})")
        solid = solid.simplify(tolerance)
        tolerance *= _GROWTH
    return to_trimesh(solid)
