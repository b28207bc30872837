"""The NASA almond (Woo et al., IEEE AP Magazine 35(1), 1993), the RCS benchmark target.

With d the length and t in [-0.416667, 0.583333], the cross-section at x = d t is an ellipse
with semi-axes (a_y, a_z) = (0.193333 d, 0.064444 d) sqrt(1 - (t / 0.416667)^2) on the rounded
half (t < 0) and (4.83345 d, 1.61115 d) [sqrt(1 - (t / 2.08335)^2) - 0.96] on the pointed half.
The pointed tip is at x = +0.583333 d, the rounded end at x = -0.416667 d; the almond is flat in
z. Rings are spaced evenly in arc length on the rounded cap (t = t0 cos theta) and evenly in t
on the pointed half; both ends close on a single vertex.
"""

from __future__ import annotations

import numpy as np
import trimesh

ALMOND_LENGTH_M = 0.252374  # 9.936 in, the Austin RCS benchmark's smallest almond
_T_BACK, _T_TIP = -0.416667, 0.583333


def almond_semi_axes(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a_y, a_z) / d of the cross-section at x = d t."""
    t = np.asarray(t, dtype=np.float64)
    back = np.sqrt(np.clip(1.0 - (t / 0.416667) ** 2, 0.0, None))
    front = np.clip(np.sqrt(np.clip(1.0 - (t / 2.08335) ** 2, 0.0, None)) - 0.96, 0.0, None)
    a_y = np.where(t < 0, 0.193333 * back, 4.83345 * front)
    a_z = np.where(t < 0, 0.064444 * back, 1.61115 * front)
    return a_y, a_z


def nasa_almond(length_m: float = ALMOND_LENGTH_M, n_around: int = 128, n_back: int = 48,
                n_front: int = 96) -> trimesh.Trimesh:
    """Closed almond mesh of length ``length_m`` (tip at +x), outward normals."""
    theta = np.linspace(0.0, np.pi / 2, n_back + 1)[1:]  # excludes the rounded end itself
    t = np.concatenate([_T_BACK * np.cos(theta), np.linspace(0.0, _T_TIP, n_front + 1)[1:-1]])
    a_y, a_z = almond_semi_axes(t)
    psi = np.linspace(-np.pi, np.pi, n_around, endpoint=False)
    rings = np.stack(
        [np.repeat(t, n_around), (a_y[:, None] * np.cos(psi)).ravel(), (a_z[:, None] * np.sin(psi)).ravel()], axis=1
    )
    vertices = np.vstack([[[_T_BACK, 0.0, 0.0]], rings, [[_T_TIP, 0.0, 0.0]]]) * length_m
    n_rings, last = len(t), len(rings) + 1
    j = np.arange(n_around)
    jn = (j + 1) % n_around
    faces = [np.stack([np.zeros(n_around, int), 1 + jn, 1 + j], axis=1)]  # back cap fan
    for i in range(n_rings - 1):
        a, b = 1 + i * n_around, 1 + (i + 1) * n_around
        faces.append(np.stack([a + j, a + jn, b + jn], axis=1))
        faces.append(np.stack([a + j, b + jn, b + j], axis=1))
    a = 1 + (n_rings - 1) * n_around
    faces.append(np.stack([a + j, a + jn, np.full(n_around, last)], axis=1))  # tip fan
    mesh = trimesh.Trimesh(vertices, np.concatenate(faces), process=False)
    if mesh.volume < 0:
        mesh.invert()
    return mesh
