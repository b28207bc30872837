"""Analytic test shapes inside the unit cube with their SDFs, and batches in the contract's keys.

The primitives' SDFs are exact; the two unions (min of exact SDFs) are exact outside and a bound
inside. Signs, occupancy labels and surface points are exact (no mesh, no sampling error), so a
failing overfit test is the model's fault. Surface points are drawn uniformly in a thin band
round the surface and projected onto it along the SDF gradient (area-uniform up to the band's
curvature term).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch.utils.data import Dataset

SDF = Callable[[np.ndarray], np.ndarray]
PAD = 0.55  # half-extent of the padded cube used for uniform samples (docs/design.md section 6)


def sphere(p, r=0.35, c=(0.0, 0.0, 0.0)):
    return np.linalg.norm(p - np.asarray(c), axis=-1) - r


def box(p, half=(0.3, 0.2, 0.35), c=(0.0, 0.0, 0.0), rounding=0.0):
    q = np.abs(p - np.asarray(c)) - (np.asarray(half) - rounding)
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0) - rounding


def capsule(p, a=(-0.2, -0.2, -0.1), b=(0.2, 0.2, 0.1), r=0.15):
    a, b = np.asarray(a), np.asarray(b)
    t = np.clip(((p - a) @ (b - a)) / ((b - a) @ (b - a)), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * (b - a)), axis=-1) - r


def cylinder(p, r=0.25, half_height=0.35):
    d = np.stack([np.linalg.norm(p[:, :2], axis=-1) - r, np.abs(p[:, 2]) - half_height], -1)
    return np.minimum(d.max(-1), 0.0) + np.linalg.norm(np.maximum(d, 0.0), axis=-1)


def torus(p, major=0.3, minor=0.1):
    q = np.stack([np.linalg.norm(p[:, :2], axis=-1) - major, p[:, 2]], -1)
    return np.linalg.norm(q, axis=-1) - minor


SHAPES: dict[str, SDF] = {
    "sphere": sphere,
    "box": box,
    "capsule": capsule,
    "cylinder": cylinder,
    "torus": torus,
    "rounded_box": lambda p: box(p, half=(0.35, 0.3, 0.15), rounding=0.08),
    "sphere_box": lambda p: np.minimum(sphere(p, 0.2, (-0.2, 0.0, 0.0)), box(p, (0.15, 0.15, 0.15), (0.2, 0.05, 0.0))),
    "cross": lambda p: np.minimum(
        capsule(p, (-0.35, 0.0, 0.0), (0.35, 0.0, 0.0), 0.1), capsule(p, (0.0, -0.1, -0.35), (0.0, 0.1, 0.35), 0.12)
    ),
}


def gradient(sdf: SDF, p: np.ndarray, eps: float = 1e-5) -> np.ndarray:
    """Central-difference gradient of ``sdf`` at ``p [N, 3]``."""
    offsets = np.eye(3) * eps
    return np.stack([(sdf(p + o) - sdf(p - o)) / (2 * eps) for o in offsets], -1)


def surface_samples(sdf: SDF, n: int, rng: np.random.Generator, band: float = 0.03) -> tuple[np.ndarray, np.ndarray]:
    """``n`` points on the zero level set and their unit normals (float32)."""
    found: list[np.ndarray] = []
    while sum(len(f) for f in found) < n:
        p = rng.uniform(-PAD, PAD, size=(100_000, 3))
        found.append(p[np.abs(sdf(p)) < band])
    p = np.concatenate(found)[:n]
    for _ in range(3):  # exact SDF: one step lands on the surface; the rest cleans up unions
        g = gradient(sdf, p)
        p = p - sdf(p)[:, None] * g / np.linalg.norm(g, axis=-1, keepdims=True)
    g = gradient(sdf, p)
    return p.astype(np.float32), (g / np.linalg.norm(g, axis=-1, keepdims=True)).astype(np.float32)


def shape_record(name: str, seed: int = 0, n_surface: int = 20_000, n_sdf: int = 40_000, n_occ: int = 50_000) -> dict:
    """Numpy arrays for one shape: surface points/normals, SDF samples, occupancy, eval points.

    SDF samples: half near the surface (Gaussian offsets, std 0.01 and 0.05), half uniform.
    """
    sdf = SHAPES[name]
    rng = np.random.default_rng(seed)
    surface, normals = surface_samples(sdf, n_surface + n_sdf // 2, rng)
    near = surface[n_surface:] + rng.normal(size=(n_sdf // 2, 3)) * rng.choice([0.01, 0.05], size=(n_sdf // 2, 1))
    sdf_points = np.concatenate([near, rng.uniform(-PAD, PAD, size=(n_sdf - n_sdf // 2, 3))]).astype(np.float32)
    occ = rng.uniform(-PAD, PAD, size=(n_occ, 3)).astype(np.float32)
    return {
        "surface_points": surface[:n_surface],
        "surface_normals": normals[:n_surface],
        "sdf_points": sdf_points,
        "sdf_values": sdf(sdf_points.astype(np.float64)).astype(np.float32),
        "eval_points": surface_samples(sdf, n_surface, rng)[0],
        "occ_points": occ,
        "occ_inside": sdf(occ.astype(np.float64)) < 0,
    }


class AnalyticShapeDataset(Dataset):
    """One item per shape with fresh random subsets each access (like a training DataModule)."""

    def __init__(self, names: Sequence[str], n_surface: int = 1024, n_sdf: int = 2048, seed: int = 0) -> None:
        self.names = list(names)
        self.records = [shape_record(n, seed + i) for i, n in enumerate(self.names)]
        self.n_surface, self.n_sdf = n_surface, n_sdf
        self.rng = np.random.default_rng(seed)

    def __len__(self) -> int:
        return len(self.names)

    def __getitem__(self, i: int) -> dict:
        rec = self.records[i]
        s = self.rng.choice(len(rec["surface_points"]), self.n_surface, replace=False)
        q = self.rng.choice(len(rec["sdf_points"]), self.n_sdf, replace=False)
        return {
            "surface_points": torch.from_numpy(rec["surface_points"][s]),
            "sdf_points": torch.from_numpy(rec["sdf_points"][q]),
            "sdf_values": torch.from_numpy(rec["sdf_values"][q]),
            "index": torch.tensor(i),
        }

    def eval_batch(self, n_eval: int = 10_000, n_occ: int = 50_000) -> dict:
        """All shapes at once with fixed surface inputs and the metric keys (eval/occ points)."""
        keys = ("surface_points", "eval_points", "occ_points", "occ_inside")
        sizes = (self.n_surface, n_eval, n_occ, n_occ)
        batch = {k: torch.stack([torch.from_numpy(r[k][:n]) for r in self.records]) for k, n in zip(keys, sizes)}
        batch["index"] = torch.arange(len(self.records))
        batch["label"] = torch.zeros(len(self.records), dtype=torch.long)
        return batch
