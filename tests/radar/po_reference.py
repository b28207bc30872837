"""Slow, obviously-correct PO oracle for the fast simulator (float64, one facet at a time).

Per direction and facet: back-face test, a brute-force Moller-Trumbore occlusion ray against every
triangle, then the triangle integral I = int exp(2jk u.r) dS from the symmetric closed form
2A sum_i e^{j a_i} / prod_{m != i} j (a_i - a_m) when the a_i are well apart, else Gauss-Legendre
quadrature on the collapsed (Duffy) square with enough points for the phase span.
S = -j k / sqrt(pi) * sum (n.u) I.  Shares nothing with radar2shape.radar except conventions.
"""

from __future__ import annotations

import numpy as np

C0 = 299_792_458.0
RAY_OFFSET = 1e-5  # fraction of the bbox diagonal, as in the fast path


def triangle_integral(tri: np.ndarray, u: np.ndarray, k: np.ndarray) -> np.ndarray:
    """int over triangle tri [3, 3] of exp(2jk u.r) dS for every k, complex128 [N]."""
    area = 0.5 * np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0]))
    s = 2.0 * tri @ u  # a_i = k s_i
    gap = min(abs(s[0] - s[1]), abs(s[1] - s[2]), abs(s[0] - s[2])) * k.min()
    if gap > 1e-2:
        a = np.outer(k, s)  # [N, 3]
        total = np.zeros(len(k), dtype=complex)
        for i in range(3):
            den = np.ones(len(k), dtype=complex)
            for m in range(3):
                if m != i:
                    den *= 1j * (a[:, i] - a[:, m])
            total += np.exp(1j * a[:, i]) / den
        return 2.0 * area * total
    span = (s.max() - s.min()) * k.max()
    n = int(span / 2) + 30
    x, w = np.polynomial.legendre.leggauss(n)
    x, w = (x + 1) / 2, w / 2
    ss, tt = np.meshgrid(x, x, indexing="ij")
    ws = np.outer(w, w) * ss  # Duffy Jacobian s
    pts = tri[0] + ss[..., None] * (tri[1] - tri[0]) + (ss * tt)[..., None] * (tri[2] - tri[1])
    phase = 2.0 * pts @ u  # [n, n]
    vals = np.exp(1j * k[:, None, None] * phase[None]) * ws[None]
    return 2.0 * area * vals.sum(axis=(1, 2))


def ray_hits_any(origin: np.ndarray, direction: np.ndarray, tris: np.ndarray) -> bool:
    """Moller-Trumbore against every triangle [T, 3, 3]; hit means t > 0."""
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    pvec = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, pvec)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tvec = origin - tris[:, 0]
    uu = np.einsum("ij,ij->i", tvec, pvec) * inv
    qvec = np.cross(tvec, e1)
    vv = (qvec @ direction) * inv
    t = np.einsum("ij,ij->i", e2, qvec) * inv
    return bool(np.any(ok & (uu >= 0) & (vv >= 0) & (uu + vv <= 1) & (t > 0)))


def reference_po(vertices, faces, aspect_rad, roll_rad, freq_hz, shadowing=True) -> np.ndarray:
    """complex128 [A, R, N]; every facet of every direction handled on its own."""
    vertices = np.asarray(vertices, dtype=float)
    tris = vertices[np.asarray(faces)]
    k = 2 * np.pi * np.asarray(freq_hz, dtype=float) / C0
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    normals = cross / np.linalg.norm(cross, axis=1, keepdims=True)
    offset = RAY_OFFSET * np.linalg.norm(vertices.max(0) - vertices.min(0))
    out = np.zeros((len(aspect_rad), len(roll_rad), len(k)), dtype=complex)
    for ia, a in enumerate(aspect_rad):
        for ir, p in enumerate(roll_rad):
            u = np.array([np.sin(a) * np.cos(p), np.sin(a) * np.sin(p), np.cos(a)])
            for tri, n in zip(tris, normals):
                c = n @ u
                if c <= 0:
                    continue
                if shadowing and ray_hits_any(tri.mean(0) + offset * n, u, tris):
                    continue
                out[ia, ir] += -1j * k / np.sqrt(np.pi) * c * triangle_integral(tri, u, k)
    return out
