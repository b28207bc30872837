"""The mesh pipeline every record goes through: repair, simplify, normalise.

Procedural shapes pass the repair and budget checks untouched; real meshes may be fixed,
unioned or remeshed (see ``geometry.repair``) and then simplified to the face budget, which
bounds the cost of the radar simulation and of the distance queries.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from radar2shape.geometry.mesh_io import MeshError
from radar2shape.geometry.normalise import normalise
from radar2shape.geometry.repair import is_solid, make_watertight
from radar2shape.geometry.simplify import simplify


@dataclass(frozen=True)
class MeshConfig:
    """Limits of the mesh pipeline (the ``mesh`` section of a data config)."""

    face_budget: int = 8000  # at most this many faces after simplification
    remesh_resolution: int = 128  # signed-distance grid for meshes simple repair cannot close
    max_input_faces: int = 5_000_000  # larger inputs are skipped (memory), not processed


@dataclass
class PreparedMesh:
    """A normalised watertight mesh and the transform and repair step that produced it."""

    mesh: trimesh.Trimesh
    centre: np.ndarray
    scale: float
    repair: str


def prepare_mesh(mesh: trimesh.Trimesh, config: MeshConfig) -> PreparedMesh:
    """Repair to a watertight solid, simplify to the face budget, normalise to the unit cube."""
    if len(mesh.faces) > config.max_input_faces:
        raise MeshError(f"{len(mesh.faces)} faces, more than mesh.max_input_faces = {config.max_input_faces}")
    solid, step = make_watertight(mesh, config.remesh_resolution)
    solid = simplify(solid, config.face_budget)
    if not is_solid(solid):
        raise MeshError(f"not watertight after repair ({step}) and simplification")
    normalised, centre, scale = normalise(solid)
    return PreparedMesh(normalised, centre, scale, step)
