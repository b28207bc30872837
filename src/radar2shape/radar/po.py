"""Physical-optics kernel: exact triangle integrals summed over facets for many directions and
uniformly spaced wavenumbers at once (docs/design.md section 5; derivations in docs/radar.md).

For one facet seen from u, with p_m = u.e_m (p_0 + p_1 + p_2 = 0) and E_i = exp(2jk u.r_i),
the symmetric closed form is

    I = (1/k^2) sum_i b_i E_i,   b_i = A p_{i+1} / (2 p_0 p_1 p_2)   (vertex form),

whose coefficients do not depend on k. Summed over facets, the vertex terms collapse onto the
unique mesh vertices and the body becomes one non-uniform DFT per direction,
sum_v B_v exp(jk phi_v), evaluated for all frequencies by one batched real matrix product.
Where the vertex form would lose digits, a (facet, direction) pair uses instead:

* centroid form, when every k_max |p_m| <= TAU_CENTROID (face-on or electrically small):
  I = A E_c sum_n 2 j^n h_n(d) / (n + 2)!,  d_i = 2k u.(r_i - r_c), h_n the complete homogeneous
  symmetric polynomials (the exact Taylor series of the symmetric form);
* edge form, when one edge is nearly perpendicular to u (k_min |p_m| < TAU_EDGE): the two
  vertex terms of that edge merge into exp(2jk u.c_m) sinc(k p_m), regular as p_m -> 0.

Both are "entries": a polynomial in k times one phase exp(2jk u.r), evaluated per entry.
The choice is made per (facet, direction, frequency block) from k_min and k_max of the block.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse

from radar2shape.radar.facets import FacetMesh

SPEED_OF_LIGHT = 299_792_458.0
TAU_CENTROID = 0.5  # centroid form when all |k p_m| <= this (then |d_i| <= 2/3)
TAU_EDGE = 0.05  # edge form when one |k p_m| < this; TAU_CENTROID >= 2 * MAX_BAND_RATIO * TAU_EDGE
MAX_BAND_RATIO = 2.0  # k_max / k_min within one frequency block, so the thresholds hold band-wide
ENTRY_VALUES = 2**20  # entry x frequency values evaluated at once (memory bound for many frequencies)
_SQRT_PI = math.sqrt(math.pi)
_TWO_PI = 2.0 * math.pi


def wavenumbers(freq_hz: np.ndarray) -> np.ndarray:
    return 2.0 * np.pi * np.asarray(freq_hz, dtype=np.float64) / SPEED_OF_LIGHT


def frequency_blocks(k: np.ndarray, max_ratio: float = MAX_BAND_RATIO) -> list[slice]:
    """Split wavenumbers into runs that are uniformly spaced and span at most ``max_ratio``."""
    blocks, start, n = [], 0, len(k)
    while start < n:
        stop = start + 1
        step = k[stop] - k[start] if stop < n else 0.0
        while stop < n and step != 0.0:
            lo, hi = min(k[start], k[stop]), max(k[start], k[stop])
            if hi > max_ratio * lo or abs(k[stop] - k[stop - 1] - step) > 1e-9 * hi:
                break
            stop += 1
        blocks.append(slice(start, stop))
        start = stop
    return blocks


def complex_dtype(real_dtype):
    return np.result_type(real_dtype, np.complex64)


def cis(angle: np.ndarray, real_dtype=np.float64) -> np.ndarray:
    """exp(j angle), wrapped to (-pi, pi] in float64 first so float32 keeps ~1e-7 rad."""
    turns = angle * (1.0 / _TWO_PI)
    turns -= np.rint(turns)
    wrapped = turns.astype(real_dtype, copy=False)
    wrapped *= _TWO_PI
    out = np.empty(angle.shape, dtype=complex_dtype(real_dtype))
    np.cos(wrapped, out=out.real)
    np.sin(wrapped, out=out.imag)
    return out


def _split(n: int) -> tuple[int, int]:
    """n <= n1 * n2 with n1, n2 about sqrt(n): index n = n2 * m + r, m < n1, r < n2."""
    n1 = math.isqrt(max(n - 1, 0)) + 1
    return n1, -(-n // n1)


def phase_sums(phi: np.ndarray, coef: np.ndarray, k: np.ndarray, real_dtype) -> np.ndarray:
    """sum_p coef[d, p] exp(j k_n phi[d, p]) for uniformly spaced k, as [D, N].

    With k_n = k_0 + (n2 m + r) dk the sum is a batched product of
    A[d, m, p] = coef e^{j k_0 phi} e^{j n2 m dk phi} and B[d, r, p] = e^{j r dk phi}: three
    complex exponentials and ~2 sqrt(N) products per term instead of N exponentials. The
    product runs as one real BLAS matmul on the interleaved (re, im) views: with b~ = conj(B),
    re(A B) = A . b~ and im(A B) = A . (j b~), so the right-hand side is [b~; j b~].
    """
    n = len(k)
    w0 = coef * cis(k[0] * phi, real_dtype)
    if n == 1:
        return w0.sum(axis=1, keepdims=True)
    n1, n2 = _split(n)
    dk = k[1] - k[0]
    d, p = phi.shape
    a = np.empty((d, n1, p), dtype=w0.dtype)
    a[:, 0] = w0
    if n1 > 1:
        step = cis((n2 * dk) * phi, real_dtype)
        for m in range(1, n1):
            np.multiply(a[:, m - 1], step, out=a[:, m])
    rhs = np.empty((d, 2 * n2, p), dtype=w0.dtype)
    rhs[:, 0] = 1.0
    if n2 > 1:
        rhs[:, 1] = cis(-dk * phi, real_dtype)
        for r in range(2, n2):
            np.multiply(rhs[:, r - 1], rhs[:, 1], out=rhs[:, r])
    np.multiply(rhs[:, :n2], 1j, out=rhs[:, n2:])
    real = a.view(real_dtype) @ rhs.view(real_dtype).transpose(0, 2, 1)  # [D, n1, 2 n2]
    out = np.empty((d, n1, n2), dtype=w0.dtype)
    out.real, out.imag = real[..., :n2], real[..., n2:]
    return out.reshape(d, n1 * n2)[:, :n]


def entry_phases(phi: np.ndarray, k: np.ndarray, real_dtype) -> np.ndarray:
    """exp(j k_n phi_q) as [Q, N] for uniformly spaced k, with the same sqrt(N) factorisation."""
    n = len(k)
    if n == 1:
        return cis(k[0] * phi, real_dtype)[:, None]
    n1, n2 = _split(n)
    dk = k[1] - k[0]
    rows = cis(phi[:, None] * (k[0] + (n2 * dk) * np.arange(n1)), real_dtype)
    cols = cis(phi[:, None] * (dk * np.arange(n2)), real_dtype)
    out = np.multiply(rows[:, :, None], cols[:, None, :]).reshape(len(phi), n1 * n2)
    return out if n1 * n2 == n else np.ascontiguousarray(out[:, :n])


def _entries(out, d_idx, phi, k, real_dtype, re, im=None) -> None:
    """out[d_idx[q]] += amp[q, n] exp(j k_n phi_q) with amp = re_coef @ re_powers + j im_coef @ im_powers.

    ``re``/``im`` are (coef [Q, L], powers [L, N]) pairs (a polynomial in k per entry). Entries
    go in slices of about ENTRY_VALUES values; a sparse direction x entry product sums them.
    """
    step = max(1, ENTRY_VALUES // len(k))
    for s in range(0, len(d_idx), step):
        sl = slice(s, s + step)
        values = entry_phases(phi[sl], k, real_dtype)
        amp = (re[0][sl] @ re[1]).astype(real_dtype)
        if im is None:
            values.view(real_dtype).reshape(values.shape + (2,))[...] *= amp[..., None]
        else:
            values *= amp + 1j * (im[0][sl] @ im[1]).astype(real_dtype)
        rows = d_idx[sl]
        # column q of the [D, Q] selection holds a single 1 at row d_idx[q]: no sorting needed
        select = scipy.sparse.csc_array((np.ones(len(rows), dtype=real_dtype), rows, np.arange(len(rows) + 1)),
                                        shape=(len(out), len(rows)))
        out += (select @ values.view(real_dtype)).view(values.dtype)


def _series_length(x_max: float, real_dtype) -> int:
    """Terms n < L of a series bounded by x^n / n! so that the remainder is below the dtype's eps."""
    eps = np.finfo(real_dtype).eps * 1e-2
    n, term = 1, 1.0
    while term > eps:
        term *= x_max / n
        n += 1
    return n


def _centroid_entries(out, facets, directions, p, weight, d_idx, f_idx, k, real_dtype) -> None:
    """S = -j k/sqrt(pi) cA E_c sum_n j^n t_n (k/k_hi)^n for face-on or electrically small facets.

    t_n = 2 h_n(d) / (n+2)!, d_i = 2 k_hi u.(r_i - r_c) = 2 k_hi (p_{i-1} - p_i) / 3, |d_i| <= 2/3.
    With e1 = sum d_i = 0 the generating function prod 1/(1 - d_i x) = 1/(1 + e2 x^2 - e3 x^3)
    gives h_n = -e2 h_{n-2} + e3 h_{n-3}.  ``p`` is [3, Q]; arrays are [term, entry].
    """
    k_hi = float(np.abs(k).max())
    d = (2.0 * k_hi / 3.0) * (p[[2, 0, 1]] - p)
    e2 = d[0] * d[1] + d[0] * d[2] + d[1] * d[2]
    e3 = d[0] * d[1] * d[2]
    n_terms = _series_length(float(np.abs(d).max()), real_dtype)
    h = np.zeros((n_terms, len(e2)))
    h[0] = 1.0
    for n in range(2, n_terms):
        h[n] = -e2 * h[n - 2]
        if n >= 3:
            h[n] += e3 * h[n - 3]
    n = np.arange(n_terms)
    scale = np.array([2.0 * (-1.0) ** (i // 2) / math.factorial(i + 2) for i in n])  # j^n = (-1)^(n//2) j^(n%2)
    t = h * scale[:, None] * (weight / _SQRT_PI)
    powers = k[None, :] * (k / k_hi)[None, :] ** n[:, None]  # one extra k from the PO prefactor
    # -j j^n t: odd n give the real part, even n the imaginary part (with a minus sign).
    phi = 2.0 * np.einsum("ij,ij->i", directions[d_idx], facets.centroids[f_idx])
    _entries(out, d_idx, phi, k, real_dtype, re=(t[1::2].T, powers[1::2]), im=(-t[0::2].T, powers[0::2]))


def _edge_entries(out, facets, directions, p_small, p_next, weight, d_idx, f_idx, m, k, real_dtype) -> None:
    """S = cA / (sqrt(pi) p_{m+1}) sinc(k p_m) exp(2jk u.c_m) for an edge nearly normal to u."""
    x2 = (p_small * np.abs(k).max()) ** 2
    n_terms = _series_length(float(np.sqrt(x2.max())), real_dtype) // 2 + 1  # sinc has x^(2l) / (2l+1)!
    taylor = np.array([(-1.0) ** i / math.factorial(2 * i + 1) for i in range(n_terms)])
    coef = np.empty((n_terms, len(x2)))
    coef[0] = weight / (_SQRT_PI * p_next)
    for i in range(1, n_terms):
        coef[i] = coef[i - 1] * x2
    coef *= taylor[:, None]
    powers = (k / np.abs(k).max())[None, :] ** (2 * np.arange(n_terms)[:, None])
    phi = 2.0 * np.einsum("ij,ij->i", directions[d_idx], facets.midpoints[f_idx, m])
    _entries(out, d_idx, phi, k, real_dtype, re=(coef.T, powers))


def po_block(facets: FacetMesh, directions: np.ndarray, cosine: np.ndarray, lit: np.ndarray,
             k: np.ndarray, real_dtype=np.float32) -> np.ndarray:
    """PO response [D, N] (phase origin at facets.origin) of the lit facets for one block.

    ``directions`` [D, 3] unit vectors, ``cosine`` [F, D] = n.u, ``lit`` [F, D] the facets that
    carry current, ``k`` [N] a uniformly spaced block with max/min <= MAX_BAND_RATIO.
    Facet-major [F, D] layout: the per-corner coefficients [3F, D] then reach the unique
    vertices through one sparse product with contiguous rows.
    """
    k_lo, k_hi = float(np.abs(k).min()), float(np.abs(k).max())
    p = np.empty((3,) + cosine.shape)
    np.matmul(facets.edges[:, 0], directions.T, out=p[0])
    np.matmul(facets.edges[:, 1], directions.T, out=p[1])
    np.add(p[0], p[1], out=p[2])
    np.negative(p[2], out=p[2])  # exact closure: the vertex form stays the integral of a nearby facet
    # Below, per-facet coefficients only need the output's precision (p stays float64 for the
    # entries): a float32 b_i carries the same relative error as the float32 phase sum after it.
    pw = p.astype(real_dtype, copy=False)
    size = np.abs(pw)
    centroid = lit & (size.max(axis=0) <= TAU_CENTROID / k_hi)
    edge = lit & (size.min(axis=0) < TAU_EDGE / k_lo) & ~centroid
    vertex = lit & ~(centroid | edge)
    weight = cosine * facets.areas[:, None]  # cA; only read where lit

    out = np.zeros((len(directions), len(k)), dtype=complex_dtype(real_dtype))
    # Vertex form: b_i = cA p_{i+1} / (2 p0 p1 p2), zero where another form (or no current) applies.
    denom = pw[0] * pw[1]
    denom *= pw[2]
    denom *= 2.0
    base = np.divide(weight.astype(real_dtype, copy=False), denom, out=np.zeros_like(denom), where=vertex)
    beta = np.empty_like(pw)
    for i in range(3):
        np.multiply(base, pw[(i + 1) % 3], out=beta[i])

    # Edge form for the small edge m: vertex m+2 keeps Q = cA / (2 p_{m+1} p_{m+2}), vertex m
    # gets -Q, vertex m+1 keeps 0 (base is 0 off the vertex form), and the edge midpoint
    # carries the sinc entry.
    f_idx, d_idx = np.nonzero(edge)
    if len(f_idx):
        pe = p[:, f_idx, d_idx]
        m = size[:, f_idx, d_idx].argmin(axis=0)
        rows = np.arange(len(m))
        ps, pa, pb = (pe[(m + i) % 3, rows] for i in range(3))
        w = weight[f_idx, d_idx]
        q = w / (2.0 * pa * pb)
        beta[(m + 2) % 3, f_idx, d_idx] = q
        beta[m, f_idx, d_idx] = -q
        _edge_entries(out, facets, directions, ps, pa, w, d_idx, f_idx, m, k, real_dtype)

    f_idx, d_idx = np.nonzero(centroid)
    if len(f_idx):
        _centroid_entries(out, facets, directions, p[:, f_idx, d_idx], weight[f_idx, d_idx],
                          d_idx, f_idx, k, real_dtype)

    coef = facets.gather.astype(real_dtype) @ beta.reshape(-1, len(directions))  # [V, D] per unique vertex
    phi = 2.0 * (directions @ facets.vertices.T)
    vertex_sum = phase_sums(phi, np.ascontiguousarray(coef.T), k, real_dtype)
    out += vertex_sum * (-1j / (_SQRT_PI * k)).astype(out.dtype)
    return out
