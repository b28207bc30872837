"""``simulate``: the monostatic radar response of a triangle mesh over aspect x roll x frequency."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from radar2shape.errors import UserInputError
from radar2shape.radar import edges, po, sbr
from radar2shape.radar.facets import FacetMesh, facet_mesh
from radar2shape.radar.heap import keep_freed_blocks
from radar2shape.radar.shadow import Occluder
from radar2shape.radar.workers import worker_count  # re-exported: callers import it from here

METHODS = ("po", "sbr", "po+ec", "sbr+ec")
# Facet-direction pairs per chunk: the [F, chunk] float64 work arrays stay near cache size
# (about 1 MB), and the Embree batch is still large enough for its call overhead not to matter.
# bench/radar.py --chunks times neighbours in one run (two quiet cores, 2,000-facet torus):
# 2**15 0.220 s, 2**16 0.161 s, 2**17 0.132 s, 2**18 0.213 s (best of 9).
CHUNK_ENTRIES = 2**17


def directions(aspect_rad: np.ndarray, roll_rad: np.ndarray) -> np.ndarray:
    """Unit vectors toward the radar, [A, R, 3]: u = (sin a cos p, sin a sin p, cos a)."""
    a, p = np.meshgrid(aspect_rad, roll_rad, indexing="ij")
    return np.stack([np.sin(a) * np.cos(p), np.sin(a) * np.sin(p), np.cos(a)], axis=-1)


def _axis(values, name: str) -> np.ndarray:
    try:
        arr = np.atleast_1d(np.asarray(values, dtype=np.float64))
    except (TypeError, ValueError) as err:
        raise UserInputError(f"{name}: expected a 1-D array of numbers ({err})") from err
    if arr.ndim != 1 or arr.size == 0:
        raise UserInputError(f"{name}: expected a non-empty 1-D array, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise UserInputError(f"{name}: contains NaN or infinite values")
    return arr


def check_axes(aspect_rad, roll_rad, freq_hz) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validated float64 axes: aspect within [0, pi], frequencies > 0 (roll is periodic)."""
    aspect, roll, freq = _axis(aspect_rad, "aspect_rad"), _axis(roll_rad, "roll_rad"), _axis(freq_hz, "freq_hz")
    eps = 1e-9
    if aspect.min() < -eps or aspect.max() > np.pi + eps:
        raise UserInputError(f"aspect_rad: must lie in [0, pi] radians, got [{aspect.min():g}, {aspect.max():g}]")
    if freq.min() <= 0:
        raise UserInputError(f"freq_hz: frequencies must be positive, got min {freq.min():g} Hz")
    return np.clip(aspect, 0.0, np.pi), roll, freq


def _real_dtype(dtype):
    dtype = np.dtype(dtype)
    if dtype == np.complex64:
        return np.float32
    if dtype == np.complex128:
        return np.float64
    raise UserInputError(f"dtype: expected complex64 or complex128, got {dtype}")


def _sbr_part(facets, u, k, names, max_bounces, rays_per_wavelength, real_dtype) -> np.ndarray:
    """SBR bounces 2.. for each asked polarisation, [D, N, P] (one ray trace: rays do not depend on it)."""
    return sbr.multibounce(facets, u, k, max_bounces, rays_per_wavelength, real_dtype, polarization=list(names))


def simulate(mesh, aspect_rad, roll_rad, freq_hz, method: str = "po", shadowing: bool = True,
             dtype=np.complex64, max_bounces: int = sbr.DEFAULT_BOUNCES,
             rays_per_wavelength: float = sbr.DEFAULT_RAYS_PER_WAVELENGTH, polarization="VV",
             edge_threshold_deg: float = edges.SHARP_EDGE_DEG,
             edge_krho: float = edges.ROUNDED_EDGE_KRHO, edge_order: int = edges.EDGE_ORDER) -> np.ndarray:
    """Complex monostatic response S [N_aspect, N_roll, N_freq] of a PEC mesh, |S|^2 = RCS (m^2).

    ``mesh`` (trimesh.Trimesh or (vertices, faces)) is in metres as given, the phase referenced
    to its coordinate origin; the radar looks from u = (sin a cos p, sin a sin p, cos a).
    ``shadowing`` adds Embree occlusion rays to back-face culling (facet-level PO shadowing,
    right for non-convex bodies). Degenerate faces are dropped.

    ``method``: "po" physical optics; "sbr" adds the shooting-and-bouncing-rays sum of bounces
    2..``max_bounces`` (``rays_per_wavelength`` at the highest frequency; radar/sbr.py,
    docs/sbr_lora.md); "po+ec" / "sbr+ec" add the equivalent edge currents of the sharp edges
    (normals turning by at least ``edge_threshold_deg``, and open boundaries; radar/edges.py),
    and of the convex rounded edges whose radius of curvature is at most ``edge_krho`` / k at each
    wavenumber k (0: none; the default 1 lights the thin rims the wave cannot resolve);
    ``edge_order`` 2 (default) adds the double diffraction between the facing edges of flat
    sheets (radar/edge_pairs.py), 1 keeps single diffraction only.

    ``polarization``: "VV" (transmit and receive theta-hat = d u / d aspect), "HH" (phi-hat =
    d u / d roll, normalised; at the poles the roll is taken as 0), "HV" (transmit H, receive V)
    or "VH" give [A, R, F]; "all" gives [A, R, F, 4] in the order VV, VH, HV, HH (a trailing
    reshape to (2, 2) is [transmit, receive] with V = 0, H = 1), and a list of names gives them
    in that order. PO alone gives S_VV = S_HH and no cross-polarisation, so the default ("VV")
    is PO's scalar response.
    """
    if method not in METHODS:
        raise UserInputError(f"method: expected one of {METHODS}, got {method!r}")
    keep_freed_blocks()  # the per-chunk work arrays stay in the heap (radar/heap.py)
    names, stacked = edges.check_polarization(polarization)
    if method.startswith("sbr"):
        sbr.check_options(max_bounces, rays_per_wavelength)
    with_edges = method.endswith("+ec")
    if with_edges:
        edges.check_threshold(edge_threshold_deg)
        edges.check_krho(edge_krho)
        edges.check_order(edge_order)
    real_dtype = _real_dtype(dtype)
    aspect, roll, freq = check_axes(aspect_rad, roll_rad, freq_hz)
    facets = mesh if isinstance(mesh, FacetMesh) else facet_mesh(mesh)
    u_all = directions(aspect, roll).reshape(-1, 3)
    # The poles repeat one direction for every roll: compute each distinct direction once
    # (kept in grid order, so a chunk holds neighbouring directions).
    _, first, inverse = np.unique(np.round(u_all, 12), axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    u, inverse = u_all[first[order]], rank[inverse.ravel()]
    k = po.wavenumbers(freq)
    blocks = po.frequency_blocks(k)
    occluder = Occluder(facets) if shadowing else None
    out = np.empty((len(u), len(k)), dtype=dtype)
    fringe = None
    if with_edges:
        diffraction = edges.EdgeDiffraction(facets, edge_threshold_deg, occluder.scene if occluder else None,
                                            krho=edge_krho, k_min=float(np.abs(k).min()), order=edge_order)
        fringe = np.zeros((len(u), len(k), len(names)), dtype=dtype)

    def run(chunk: slice) -> None:
        uc = u[chunk]
        cosine = facets.normals @ uc.T  # [F, D]
        lit = cosine > 0
        if occluder is not None:
            lit = occluder.visible(uc, lit)
        for block in blocks:
            out[chunk, block] = po.po_block(facets, uc, cosine, lit, k[block], real_dtype)
        if fringe is not None:
            fringe[chunk] = diffraction.response(uc, k, names, blocks, real_dtype)

    step = max(1, CHUNK_ENTRIES // facets.n_faces)
    chunks = [slice(s, s + step) for s in range(0, len(u), step)]
    workers = min(worker_count(), len(chunks))
    if workers > 1:
        with ThreadPoolExecutor(workers) as pool:  # numpy and BLAS release the GIL
            list(pool.map(run, chunks))
    else:
        for chunk in chunks:
            run(chunk)
    if names != ("VV",) or fringe is not None:
        out = _polarised(out, names, fringe)
        if method.startswith("sbr"):
            out += _sbr_part(facets, u, k, names, max_bounces, rays_per_wavelength, real_dtype).astype(dtype)
        out *= po.cis(np.outer(2.0 * (u @ facets.origin), k)).astype(dtype)[..., None]
        out = out[inverse].reshape(len(aspect), len(roll), len(k), len(names))
        return out if stacked else out[..., 0]
    if method == "sbr":
        out += sbr.multibounce(facets, u, k, max_bounces, rays_per_wavelength, real_dtype).astype(dtype)
    # Put back the phase of the local origin: S(origin) = S(local) exp(2jk u.o).
    out *= po.cis(np.outer(2.0 * (u @ facets.origin), k)).astype(dtype)
    out = out[inverse].reshape(len(aspect), len(roll), len(k))
    return out[..., None] if stacked else out


def _polarised(scalar: np.ndarray, names: tuple[str, ...], fringe: np.ndarray | None) -> np.ndarray:
    """[D, N, P]: PO's scalar on the co-polarised channels (zero cross-polarised) plus the fringe."""
    out = np.zeros(scalar.shape + (len(names),), dtype=scalar.dtype)
    for i, name in enumerate(names):
        if name[0] == name[1]:
            out[..., i] = scalar
    if fringe is not None:
        out += fringe
    return out
