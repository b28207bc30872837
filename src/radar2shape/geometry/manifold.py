"""Bridges between trimesh and manifold3d, the exact boolean / simplification kernel.

manifold3d guarantees manifold (watertight) output for its booleans and simplification, which is
why the procedural families and the face-budget simplifier are built on it.
"""

from __future__ import annotations

import manifold3d
import numpy as np
import trimesh


def from_trimesh(mesh: trimesh.Trimesh) -> manifold3d.Manifold:
    """A Manifold of a watertight mesh; ``ValueError`` naming the kernel's status otherwise."""
    solid = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=np.asarray(mesh.vertices, dtype=np.float32),
            tri_verts=np.asarray(mesh.faces, dtype=np.uint32),
        )
    )
    if solid.status() != manifold3d.Error.NoError:
        raise ValueError(f"not a manifold mesh ({solid.status().name})")
    return solid


def to_trimesh(solid: manifold3d.Manifold) -> trimesh.Trimesh:
    """The triangle mesh of a Manifold (float64 vertices, shared, watertight)."""
    mesh = solid.to_mesh()
    vertices = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    return trimesh.Trimesh(vertices, np.asarray(mesh.tri_verts, dtype=np.int64), process=False)


def union_all(solids: list[manifold3d.Manifold]) -> manifold3d.Manifold:
    """Exact union of many solids in one batched boolean (faster than pairwise ``+``)."""
    return manifold3d.Manifold.batch_boolean(list(solids), manifold3d.OpType.Add)
