"""Training and evaluation point sets of a normalised watertight shape.

All distances and signs come from ``geometry.query`` (exact triangle distance, ray-parity
containment), the routines the metrics use, so SDF targets, occupancy labels and scores agree.
Every sampler takes a seed, so a record is a pure function of its shape and seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from radar2shape.geometry import query


@dataclass(frozen=True)
class SamplingConfig:
    """How many points of each kind a record stores (see docs/data.md, "Record format")."""

    surface: int = 20_000  # encoder input, with normals
    eval: int = 30_000  # ground-truth surface points for Chamfer / F-score
    sdf: int = 16_384  # SDF supervision
    sdf_near_fraction: float = 0.7  # share of SDF points near the surface, the rest uniform
    sdf_near_sigmas: tuple[float, ...] = (0.005, 0.03)  # Gaussian offsets, split evenly
    occ: int = 100_000  # uniform IoU points with containment labels
    padding: float = 0.05  # the sampling cube is [-0.5 - padding, 0.5 + padding]^3


def signed_distance(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Exact distance to the surface, negative inside (float32)."""
    distance = query.unsigned_distance(mesh, points)
    return np.where(query.contains(mesh, points), -distance, distance).astype(np.float32)


def uniform_points(n: int, padding: float, rng: np.random.Generator) -> np.ndarray:
    """``n`` points uniform in the padded unit cube (float32)."""
    bound = 0.5 + padding
    return rng.uniform(-bound, bound, size=(n, 3)).astype(np.float32)


def sdf_points(mesh: trimesh.Trimesh, config: SamplingConfig, rng: np.random.Generator) -> np.ndarray:
    """Near-surface points (surface samples + Gaussian offsets at each sigma) and uniform ones,
    shuffled so that any prefix is a representative subset (evaluation takes prefixes)."""
    n_near = int(round(config.sdf * config.sdf_near_fraction))
    base, _ = query.sample_surface(mesh, n_near, rng)
    sigma = np.repeat(np.asarray(config.sdf_near_sigmas), -(-n_near // len(config.sdf_near_sigmas)))[:n_near]
    near = base + rng.normal(size=base.shape) * sigma[:, None]
    far = uniform_points(config.sdf - n_near, config.padding, rng)
    points = np.concatenate([near.astype(np.float32), far])
    return points[rng.permutation(len(points))]


def sample_shape(mesh: trimesh.Trimesh, config: SamplingConfig, seed: int) -> dict[str, np.ndarray]:
    """Every stored point set of a record, keyed as in the record format.

    Each set has its own child seed, so changing one count never changes the other sets.
    """
    rng_surface, rng_eval, rng_sdf, rng_occ = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4))
    surface, normals = query.sample_surface(mesh, config.surface, rng_surface)
    evaluation, _ = query.sample_surface(mesh, config.eval, rng_eval)
    sdf_xyz = sdf_points(mesh, config, rng_sdf)
    # float16 positions halve the largest array of a record; uniform positions lose nothing
    # at 5e-4 resolution, and the labels are computed on the rounded values.
    occ = uniform_points(config.occ, config.padding, rng_occ).astype(np.float16)
    return {
        "surface_points": surface,
        "surface_normals": normals,
        "eval_points": evaluation,
        "sdf_points": sdf_xyz,
        "sdf_values": signed_distance(mesh, sdf_xyz),
        "occ_points": occ,
        "occ_inside": query.contains(mesh, occ),
    }
