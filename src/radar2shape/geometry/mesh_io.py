"""Reading mesh files into one clean triangle mesh.

Every supported format goes through trimesh; a scene (glTF, multi-object OBJ) is merged into one
mesh with its node transforms applied, because a record describes one object. Unreadable or
degenerate input raises :class:`MeshError`, which builders turn into a "skipped: reason" entry.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from radar2shape.errors import MeshError, UserInputError  # MeshError: importable from here too

MESH_SUFFIXES = (".off", ".obj", ".ply", ".stl", ".glb", ".gltf", ".dae", ".ac")
# Formats written as one self-contained file (.gltf puts its buffers in extra files).
WRITE_SUFFIXES = (".obj", ".off", ".ply", ".stl", ".glb")


def load_mesh(path: str | Path) -> trimesh.Trimesh:
    """Load ``path`` as one triangle mesh with finite vertices and no degenerate faces."""
    path = Path(path)
    if path.suffix.lower() not in MESH_SUFFIXES:
        raise MeshError(f"{path}: unsupported suffix {path.suffix!r} (expected one of {', '.join(MESH_SUFFIXES)})")
    if path.suffix.lower() in (".ac", ".dae"):  # our readers: AC3D, and COLLADA with its unit and up axis
        from radar2shape.geometry.ac3d import read_ac3d
        from radar2shape.geometry.gazebo import load_collada

        return clean(read_ac3d(path) if path.suffix.lower() == ".ac" else load_collada(path), name=str(path))
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as err:  # trimesh raises many types for malformed files
        raise MeshError(f"{path}: cannot be read as a mesh ({type(err).__name__}: {err})") from err
    if not isinstance(loaded, trimesh.Trimesh):
        raise MeshError(f"{path}: holds no triangle mesh (got {type(loaded).__name__})")
    return clean(loaded, name=str(path))


def save_mesh(path: str | Path, mesh: trimesh.Trimesh) -> Path:
    """Write ``mesh`` atomically in the format of the suffix (one of ``WRITE_SUFFIXES``)."""
    from radar2shape.atomic import atomic_path

    path = Path(path)
    if path.suffix.lower() not in WRITE_SUFFIXES:
        raise UserInputError(f"{path}: cannot write a mesh as {path.suffix or '(no suffix)'!r} "
                             f"(expected one of {', '.join(WRITE_SUFFIXES)})")
    with atomic_path(path) as temp:
        mesh.export(temp, file_type=path.suffix.lower().lstrip("."))
    return path


def clean(mesh: trimesh.Trimesh, name: str = "mesh") -> trimesh.Trimesh:
    """Drop faces touching non-finite vertices, merge duplicate vertices, drop unused ones.

    Zero-area faces are kept on purpose: removing them opens an otherwise closed surface
    (boolean results have slivers at cone tips), and every consumer (PO, distances, ray
    parity) handles them. Raises :class:`MeshError` when no area is left.
    """
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0:
        raise MeshError(f"{name}: no triangles")
    finite = np.isfinite(vertices).all(axis=1)
    faces = faces[finite[faces].all(axis=1)]
    if len(faces) == 0:
        raise MeshError(f"{name}: every triangle has a NaN or infinite vertex")
    out = trimesh.Trimesh(vertices, faces, process=True, validate=False)  # merges duplicate vertices
    out.remove_unreferenced_vertices()
    if not out.area > 0:
        raise MeshError(f"{name}: no triangle with non-zero area")
    return out
