"""Batched mesh operations on one shared face list (TMNet's deformed template sphere).

Every shape of a batch deforms the same template, so vertices are ``[B, V, 3]`` while faces and
edges are one ``[F, 3]`` / ``[E, 2]`` long tensor; a per-shape face ``weight [B, F]`` (0 = pruned)
is how topology modification enters the sampling.
"""

from __future__ import annotations

import numpy as np
import torch
import trimesh


def icosphere(level: int, radius: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Vertices ``[V, 3]`` float32 and faces ``[F, 3]`` long of an icosphere (level 3: 642 V, 4: 2562 V)."""
    sphere = trimesh.creation.icosphere(subdivisions=int(level), radius=float(radius))
    return torch.as_tensor(sphere.vertices, dtype=torch.float32), torch.as_tensor(sphere.faces, dtype=torch.long)


def unique_edges(faces: torch.Tensor) -> torch.Tensor:
    """Undirected edges ``[E, 2]`` of a face list, each once."""
    edges = torch.cat([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]).sort(dim=1).values
    return torch.unique(edges, dim=0)


def face_areas(vertices: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """Triangle areas ``[B, F]``."""
    tri = vertices[:, faces]  # [B, F, 3, 3]
    return 0.5 * torch.linalg.cross(tri[:, :, 1] - tri[:, :, 0], tri[:, :, 2] - tri[:, :, 0]).norm(dim=-1)


def sample_faces(
    vertices: torch.Tensor, faces: torch.Tensor, n: int, weight: torch.Tensor | None = None,
    generator: torch.Generator | None = None,
) -> torch.Tensor:
    """``n`` points per shape ``[B, n, 3]``, area-uniform over faces with ``weight > 0``.

    Face choice is discrete (no gradient); the barycentric interpolation is differentiable in the
    vertices, which is how Chamfer on samples moves the mesh.
    """
    probs = face_areas(vertices, faces).detach()
    if weight is not None:
        probs = probs * weight
    probs = probs + 1e-12 * (probs.sum(-1, keepdim=True) == 0)  # all pruned/degenerate: uniform
    face = torch.multinomial(probs, n, replacement=True, generator=generator)  # [B, n]
    u, v = torch.rand(2, *face.shape, 1, generator=generator, device=vertices.device)
    flip = (u + v) > 1
    u, v = torch.where(flip, 1 - u, u), torch.where(flip, 1 - v, v)
    tri = torch.gather(vertices[:, faces], 1, face[..., None, None].expand(-1, -1, 3, 3))  # [B, n, 3, 3]
    return tri[:, :, 0] + u * (tri[:, :, 1] - tri[:, :, 0]) + v * (tri[:, :, 2] - tri[:, :, 0])


def to_trimesh(vertices: torch.Tensor, faces: torch.Tensor) -> trimesh.Trimesh:
    """One mesh ``[V, 3]`` + faces ``[F', 3]`` as a Trimesh without the vertices no face uses."""
    mesh = trimesh.Trimesh(np.asarray(vertices.detach().cpu(), dtype=np.float64), np.asarray(faces.cpu()), process=False)
    mesh.remove_unreferenced_vertices()
    return mesh
