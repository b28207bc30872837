"""Double diffraction across flat sheets: the wave one sheet edge sends along the sheet to the
facing edge, which sends it back to the radar.

First-order edge currents (radar/edges.py) give a strip the same |HH| and |VV| up to the sign of
each edge's coefficient. What sets the hard polarisation (H along the edges) apart is the wave
a boundary edge of a flat sheet diffracts along the sheet: for the soft polarisation it vanishes
on the sheet, for the hard one it does not, and the facing edge diffracts it back. That wave
fills HH's nulls and, edge-on, cancels the first-order return of the far edge: a zero-thickness
plate seen edge-on in HH does not scatter at all (the incident field already meets the boundary
condition), which single diffraction cannot reproduce.

Two parallel half-plane edges (boundaries of one flat sheet, outside angle 2 pi) a distance d
apart across the sheet, overlapping over a length L, seen from u at angle beta to their tangent
t: across the edges the problem is two-dimensional with wavenumber k_t = k sin beta, and
phi_1, phi_2 in [0, pi] are the angles between each edge's inward direction and u projected
across the edges. Uniform GTD (Kouyoumjian-Pathak) gives the two round trips 1 -> 2 -> radar and
2 -> 1 -> radar, equal by reciprocity, each counting the grazing wave once with GTD's half-field
rule for an edge lit at grazing incidence:

    S_pq += L / (2 sqrt(pi)) (p.w^)(q.w^) G exp(jk u.(c_1 + c_2)) sinc(k L u.t)
    G = 8 sqrt(2 / pi) sqrt(k_t d) exp(j (x_1 + x_2 - k_t d - pi/4)) T(sqrt x_1) T(sqrt x_2)

with w^ = t x u / |t x u| (as in radar/edges.py), c_1, c_2 the midpoints of the overlapping
parts, x_i = 2 k_t d cos^2(phi_i / 2) and T(X) = int_X^inf exp(-j tau^2) d tau. This is
-2 [sec(phi_1/2) F(x_1)] [sec(phi_2/2) F(x_2)] e^{-j pi/4} e^{-j k_t d} / sqrt(2 pi k_t d) in
the hard-coefficient normalisation of radar/edges.py, F the UTD transition function, written
through T so that it stays finite edge-on (phi = pi, where sec has its pole; there it tends to
exactly minus the far edge's first-order term) and looking along the edges (k_t -> 0: it
vanishes). Checks and the Austin plate numbers: docs/radar.md, "Double diffraction".

Pairs: half-plane edges that are parallel, lie in one plane with their faces turned toward each
other, overlap along their tangent, and have sheet under the straight path between them (checked
at PATH_SAMPLES points). Both edges must see the radar (their first-order visibility).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import fresnel

from radar2shape.radar import po
from radar2shape.radar.facets import FacetMesh

# Edge tangents (and sheet normals) count as parallel when |cos| >= 1 - this.
PARALLEL_TOL = 1e-9
# Relative slack (of the separation) for "in the sheet's plane" and "on a face".
PLANE_TOL = 1e-6
# Edge directions are grouped on their unit tangents rounded to this many decimals.
DIRECTION_DIGITS = 6
# Points of the straight path between two edges that must lie on the sheet.
PATH_SAMPLES = 9
# Pair-direction-frequency values evaluated at once (complex128 temporaries).
PAIR_VALUES = 2**20
# e^{jx} T(sqrt x): asymptotic series from this x on, with this many terms (module notes of _tail).
SERIES_FROM = 30.0
SERIES_TERMS = 7
_DOUBLE_FACTORIAL = [math.prod(range(1, 2 * m, 2)) for m in range(SERIES_TERMS)]  # (2m - 1)!!
_SCALE = 8.0 * math.sqrt(2.0 / math.pi)


@dataclass(frozen=True)
class SheetPairs:
    """Facing parallel sheet edges, one row per overlapping pair (edge indices into an EdgeSet)."""

    first: np.ndarray  # [Q] edge index
    second: np.ndarray  # [Q] edge index
    tangents: np.ndarray  # [Q, 3] the first edge's unit tangent
    inward_first: np.ndarray  # [Q, 3] unit vector in the sheet, across the first edge, toward the second
    inward_second: np.ndarray  # [Q, 3] the same from the second edge toward the first
    centre_first: np.ndarray  # [Q, 3] midpoint of the first edge's overlapping part
    centre_second: np.ndarray  # [Q, 3]
    separation: np.ndarray  # [Q] d, across the edges
    overlap: np.ndarray  # [Q] L, along them

    @property
    def n_pairs(self) -> int:
        return len(self.separation)


def _on_sheet(facets: FacetMesh, points: np.ndarray, normal: np.ndarray, tol: float) -> bool:
    """Whether every point lies on a facet of the plane through them with this normal (within tol)."""
    level = float(points[0] @ normal)
    near = (np.abs(facets.normals @ normal) >= 1.0 - PARALLEL_TOL) & (np.abs(facets.centroids @ normal - level) <= tol)
    if not near.any():
        return False
    tri = facets.vertices[facets.faces[near]]  # [T, 3, 3]
    sides = []
    for m in range(3):  # signed distance (times the side's length) of each point from each side
        a, b = tri[:, m], tri[:, (m + 1) % 3]
        cross = np.cross((b - a)[None], points[:, None, :] - a[None])  # [P, T, 3]
        sides.append((cross @ normal) / np.linalg.norm(b - a, axis=1))
    sides = np.stack(sides)  # [3, P, T]
    inside = (sides >= -tol).all(axis=0) | (sides <= tol).all(axis=0)  # either winding
    return bool(inside.any(axis=1).all())


def _parallel_candidates(edges) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i < j) of half-plane edges with the same tangent direction (up to sign, to
    DIRECTION_DIGITS): pairs are formed within each direction group, so an open surface with
    thousands of boundary edges in scattered directions does not make a quadratic number of them."""
    sheet = np.flatnonzero(edges.wedge >= 2.0 - 1e-9)
    t = edges.tangents[sheet]
    first = np.argmax(np.abs(t) > 1e-6, axis=1)  # flip each tangent so its first clear component is positive
    canonical = t * np.sign(t[np.arange(len(t)), first])[:, None]
    _, group = np.unique(np.round(canonical, DIRECTION_DIGITS), axis=0, return_inverse=True)
    group = group.ravel()
    i, j = [np.zeros(0, int)], [np.zeros(0, int)]
    for g in range(group.max(initial=-1) + 1):
        members = sheet[group == g]
        a, b = np.triu_indices(len(members), k=1)
        i.append(members[a])
        j.append(members[b])
    return np.concatenate(i), np.concatenate(j)


def sheet_pairs(edges, facets: FacetMesh) -> SheetPairs:
    """The facing, overlapping pairs of parallel half-plane edges of ``edges`` (an EdgeSet)."""
    rows: list[tuple] = []
    i, j = _parallel_candidates(edges)
    if len(i):
        t = edges.tangents[i]
        keep = np.abs(np.einsum("qk,qk->q", t, edges.tangents[j])) >= 1.0 - PARALLEL_TOL
        keep &= np.abs(np.einsum("qk,qk->q", edges.normal0[i], edges.normal0[j])) >= 1.0 - PARALLEL_TOL
        s = edges.centres[j] - edges.centres[i]
        across = s - np.einsum("qk,qk->q", s, t)[:, None] * t
        d = np.linalg.norm(across, axis=1)
        keep &= d > 0
        with np.errstate(invalid="ignore", divide="ignore"):
            keep &= np.abs(np.einsum("qk,qk->q", edges.normal0[i], across)) <= PLANE_TOL * d
            keep &= np.einsum("qk,qk->q", edges.inward0[i], across) > (1.0 - PLANE_TOL) * d
            keep &= np.einsum("qk,qk->q", edges.inward0[j], across) < -(1.0 - PLANE_TOL) * d
        for a, b in zip(i[keep], j[keep]):
            ta = edges.tangents[a]
            pa, pb = edges.centres[a] @ ta, edges.centres[b] @ ta
            lo = max(pa - edges.lengths[a] / 2, pb - edges.lengths[b] / 2)
            hi = min(pa + edges.lengths[a] / 2, pb + edges.lengths[b] / 2)
            if hi - lo <= PLANE_TOL * edges.lengths[a]:
                continue
            mid = (lo + hi) / 2
            ca, cb = edges.centres[a] + (mid - pa) * ta, edges.centres[b] + (mid - pb) * ta
            gap = float(np.linalg.norm(cb - ca))
            path = ca + np.linspace(0.1, 0.9, PATH_SAMPLES)[:, None] * (cb - ca)
            if not _on_sheet(facets, path, edges.normal0[a], PLANE_TOL * gap):
                continue
            rows.append((a, b, ta, edges.inward0[a], edges.inward0[b], ca, cb, gap, hi - lo))
    if not rows:
        empty3 = np.zeros((0, 3))
        return SheetPairs(np.zeros(0, int), np.zeros(0, int), empty3, empty3, empty3, empty3, empty3,
                          np.zeros(0), np.zeros(0))
    cols = list(zip(*rows))
    return SheetPairs(np.array(cols[0]), np.array(cols[1]), *(np.array(c, dtype=np.float64) for c in cols[2:]))


def _tail(x: np.ndarray) -> np.ndarray:
    """e^{jx} T(sqrt x) = e^{jx} int_{sqrt x}^inf exp(-j tau^2) d tau, for x >= 0 (complex128).

    Fresnel integrals below SERIES_FROM; above it the asymptotic series
    (1 / (2j sqrt x)) sum_m (-1)^m (2m - 1)!! / (2jx)^m, SERIES_TERMS terms (relative error < 1e-7),
    which also saves the exponential: most (pair, direction, frequency) values lie far from the
    transition, where the Fresnel integrals are the cost.
    """
    out = np.empty(x.shape, dtype=np.complex128)
    far = x >= SERIES_FROM
    xf = x[far]
    # With r = 1 / (2x) the m-th term is (2m - 1)!! j^m r^m: real and imaginary parts are real
    # polynomials in r^2 (Horner), and (a + jb) / (2j sqrt x) = (b - ja) / (2 sqrt x).
    r = 0.5 / xf
    r2 = r * r
    real, imag = np.zeros_like(r), np.zeros_like(r)
    for m in reversed(range(SERIES_TERMS)):
        c = _DOUBLE_FACTORIAL[m] * (-1) ** (m // 2)
        if m % 2 == 0:
            real = real * r2 + c
        else:
            imag = imag * r2 + c
    imag *= r
    scale = 0.5 / np.sqrt(xf)
    out.real[far], out.imag[far] = imag * scale, -real * scale
    xn = x[~far]
    s, c = fresnel(np.sqrt(xn) * math.sqrt(2.0 / math.pi))
    out[~far] = np.exp(1j * xn) * math.sqrt(math.pi / 2.0) * ((0.5 - c) - 1j * (0.5 - s))
    return out


def pair_response(pairs: SheetPairs, u: np.ndarray, lit: np.ndarray, k: np.ndarray, w_dot: dict,
                  polarizations: tuple[str, ...], real_dtype=np.float32) -> np.ndarray:
    """Double-diffraction response [D, N, P] (local-origin phase) of the sheet pairs.

    ``lit`` [E, D]: which edges see the radar; ``w_dot`` maps "V"/"H" to p.w^ [E, D] (edges.py).
    """
    out = np.zeros((len(u), len(k), len(polarizations)), dtype=po.complex_dtype(real_dtype))
    if pairs.n_pairs == 0:
        return out
    both = lit[pairs.first] & lit[pairs.second]  # [Q, D]
    if not both.any():
        return out
    t = pairs.tangents
    along = t @ u.T  # [Q, D]
    sin_beta = np.sqrt(np.maximum(1.0 - along**2, 0.0))
    both &= sin_beta > 1e-9
    across = u[None, :, :] - along[..., None] * t[:, None, :]  # [Q, D, 3], |.| = sin beta
    with np.errstate(invalid="ignore", divide="ignore"):
        cos1 = np.einsum("qdk,qk->qd", across, pairs.inward_first) / sin_beta
        cos2 = np.einsum("qdk,qk->qd", across, pairs.inward_second) / sin_beta
    half1 = np.where(both, (1.0 + np.clip(cos1, -1, 1)) / 2, 0.0)  # cos^2(phi / 2)
    half2 = np.where(both, (1.0 + np.clip(cos2, -1, 1)) / 2, 0.0)
    amp = np.stack([(pairs.overlap[:, None] / (2.0 * math.sqrt(math.pi))) * w_dot[name[1]][pairs.first]
                    * w_dot[name[0]][pairs.first] * both for name in polarizations])  # [P, Q, D]
    phase = u @ (pairs.centre_first + pairs.centre_second).T  # [D, Q]
    sweep = (u @ t.T) * pairs.overlap  # [D, Q] L u.t
    q_idx, d_idx = np.nonzero(both)
    step = max(1, PAIR_VALUES // len(k))
    for s in range(0, len(q_idx), step):
        q, d = q_idx[s:s + step], d_idx[s:s + step]
        ktd = np.outer(sin_beta[q, d] * pairs.separation[q], k)  # [M, N] k_t d
        x1, x2 = 2.0 * ktd * half1[q, d, None], 2.0 * ktd * half2[q, d, None]
        value = _SCALE * np.sqrt(ktd) * _tail(x1) * _tail(x2)
        value *= np.exp(1j * (np.outer(phase[d, q], k) - ktd - math.pi / 4))
        arg = np.outer(sweep[d, q], k)
        value *= np.sinc(arg / math.pi)
        for p in range(len(polarizations)):
            np.add.at(out[..., p], d, (amp[p, q, d][:, None] * value).astype(out.dtype))
    return out
