"""Bringing a mesh into the body frame (docs/design.md section 4).

The body frame is z up: aspect is measured from +z and roll about z from +x. Mesh formats
disagree about "up" (AC3D and glTF: y; ModelNet and Gazebo: z; COLLADA says it in the file), so
the caller states it and this module turns the mesh with a proper rotation (det +1, never a
mirror, which would reverse roll). The other axes follow the right-handed rule: y up maps
(x, y, z) -> (x, -z, y), so an AC3D aircraft keeps its fuselage along x.
"""

from __future__ import annotations

import numpy as np
import trimesh

from radar2shape.errors import UserInputError

UP_AXES = ("x", "y", "z", "-x", "-y", "-z")

# Rows are the body-frame axes written in the source frame: body = R @ source.
_ROTATIONS = {
    "z": np.eye(3),
    "y": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),  # quarter turn about +x: y -> z, z -> -y
    "x": np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]]),  # quarter turn about +y (negative): x -> z, z -> -x
    "-z": np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, -1]]),  # half turn about +x
    "-y": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),  # quarter turn about +x (negative): -y -> z
    "-x": np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]),  # quarter turn about +y: -x -> z
}


def up_rotation(up: str) -> np.ndarray:
    """The 3x3 rotation that takes the source's ``up`` axis onto +z."""
    key = str(up).strip().lower()
    if key not in _ROTATIONS:
        raise UserInputError(f"up: expected one of {', '.join(UP_AXES)}, got {up!r}")
    return _ROTATIONS[key].copy()


def to_body_frame(mesh: trimesh.Trimesh, up: str) -> trimesh.Trimesh:
    """A copy of ``mesh`` turned so that its ``up`` axis is +z (faces and winding unchanged)."""
    rotation = up_rotation(up)
    vertices = np.asarray(mesh.vertices, dtype=np.float64) @ rotation.T
    return trimesh.Trimesh(vertices, np.asarray(mesh.faces).copy(), process=False)
