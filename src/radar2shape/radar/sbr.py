"""Shooting and bouncing rays (Ling, Chou & Lee 1989) for the multi-bounce part of the response.

The simulator's ``method="sbr"`` is a hybrid: exact facet PO (with shadowing) for the first
bounce, plus :func:`multibounce` here for bounces 2..max_bounces. Derivation and checks in
docs/sbr_lora.md. Per direction u, square ray tubes of side ``delta`` (``lambda_min /
rays_per_wavelength``) leave a plane just outside the bounding sphere toward -u and carry a real
field vector E (the transmit polarisation: theta-hat of u for V, phi-hat for H) and a path
length L. At each hit (PEC): D' = D - 2 (D.n) n, E' = -E + 2 (n.E) n. From the second hit on,
each hit radiates back toward u with the PO integral over its tube footprint (n oriented toward
the incoming ray):

    S_ray = -j k/sqrt(pi) * e_r.[D (n.E) - E (n.D)] * delta^2/|n.D| * sinc(k c1) sinc(k c2)
            * exp(jk (u.r + R_s - L)),

where e_r is the receive polarisation, c_i = delta w.b_i / 2 with w = u - D and b_i the tube's
cross-section axes projected along D onto the facet plane. With one bounce this is PO
(|S|^2 = RCS in m^2, phase referenced to the local origin), which the tests check on a plate.

Work is split into batches of at most ``rays_per_batch`` launched rays (a fixed plan that does
not depend on the worker count), traced in worker processes: embreex holds the GIL, so threads
would not overlap. Each batch's partial sum goes back to the parent, which adds them in batch
order, so any worker count gives the same numbers.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import pickle
import tempfile
import threading
import uuid
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.spatial
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from radar2shape.errors import UserInputError
from radar2shape.radar import po
from radar2shape.radar.edges import polarisation_basis
from radar2shape.radar.facets import FacetMesh
from radar2shape.radar.workers import worker_count

DEFAULT_BOUNCES = 5
DEFAULT_RAYS_PER_WAVELENGTH = 8.0
DEFAULT_RAYS_PER_BATCH = 2**16  # launched rays per batch: the memory budget (docs/sbr_lora.md)
VALUES_PER_CHUNK = 2**19  # ray x frequency values evaluated at once when summing contributions
GRAZING = 1e-6  # hits with |n.D| below this add nothing (degenerate footprint)
WINDOW_TOL = 1e-5  # silhouette window margin, relative to the bounding radius (float32 rays)
HULL_VALUES = 2**20  # direction x hull-point products per step when sizing the launch windows
# Memory of one batch (numpy arrays, measured with tracemalloc, docs/sbr_lora.md): at most about
# 450 bytes per launched ray (positions, directions, fields, tube axes, Embree results, hits) plus
# the frequency sum's ray x frequency temporaries. The bound below has a margin over both.
BYTES_PER_RAY = 512
BYTES_PER_VALUE = 64
BYTES_PER_CELL = 48  # per (direction, grid row) cell of a batch's row table
CELLS_PER_BATCH = 2**18  # direction x grid-row cells per batch (bounds that table)
# Polarisation letters: V = theta-hat of u, H = phi-hat. First letter transmit, second receive.
POLARIZATIONS = ("VV", "HH", "HV", "VH")
_BASIS = {"V": 0, "H": 1}
_SQRT_PI = math.sqrt(math.pi)


class SBRWorkerError(RuntimeError):
    """A batch failed or a worker process died; raised once in the parent."""


def check_options(max_bounces, rays_per_wavelength) -> tuple[int, float]:
    """Validated (max_bounces >= 1 integer, rays_per_wavelength > 0 finite)."""
    if isinstance(max_bounces, bool) or not isinstance(max_bounces, (int, np.integer)) or max_bounces < 1:
        raise UserInputError(f"max_bounces: expected an integer >= 1 (1 = PO only), got {max_bounces!r}")
    try:
        rpw = float(rays_per_wavelength)
    except (TypeError, ValueError):
        raise UserInputError(f"rays_per_wavelength: expected a positive number, got {rays_per_wavelength!r}") from None
    if not (math.isfinite(rpw) and rpw > 0):
        raise UserInputError(f"rays_per_wavelength: expected a positive number, got {rays_per_wavelength!r}")
    return int(max_bounces), rpw


def check_polarization(polarization) -> tuple[int, int]:
    """(transmit, receive) basis indices (0 = V = theta-hat, 1 = H = phi-hat) of e.g. "HV"."""
    name = polarization.upper() if isinstance(polarization, str) else polarization
    if name not in POLARIZATIONS:
        raise UserInputError(f"polarization: expected one of {', '.join(POLARIZATIONS)} "
                             f"(first letter transmit, second receive), got {polarization!r}")
    return _BASIS[name[0]], _BASIS[name[1]]


def check_channels(polarization) -> tuple[tuple[tuple[int, int], ...], bool]:
    """((transmit, receive) per channel, stacked): one name gives one unstacked channel."""
    if isinstance(polarization, str) or polarization is None or not hasattr(polarization, "__iter__"):
        return (check_polarization(polarization),), False
    channels = tuple(check_polarization(name) for name in polarization)
    if not channels:
        raise UserInputError(f"polarization: expected a name or a non-empty list of {', '.join(POLARIZATIONS)}, "
                             f"got {polarization!r}")
    return channels, True


def _positive_int(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise UserInputError(f"{name}: expected an integer >= 1, got {value!r}")
    return int(value)


def default_workers() -> int:
    """Worker processes when none are asked for: the simulator's count (torch threads or usable cores)."""
    return worker_count()


@dataclass(frozen=True)
class TubeGrid:
    """The launch grid of one call: square tubes of side ``delta`` covering the disk of ``radius``.

    Centres sit at half-integer multiples of delta (so a plate edge through the origin falls
    between tubes rather than on a row of them), in row-major order. Only per-row extents are
    stored, so memory grows with the square root of the tube count.
    """

    delta: float
    first: np.ndarray  # [n] column index of each row's first tube in the disk
    stop: np.ndarray  # [n] column index past each row's last tube

    @property
    def n(self) -> int:
        return len(self.first)

    @property
    def size(self) -> int:
        return int((self.stop - self.first).sum())

    def coordinate(self, index: np.ndarray) -> np.ndarray:
        """Row or column index -> offset in the launch plane (half-integer multiples of delta)."""
        return (index - self.n / 2 + 0.5) * self.delta

    def index_range(self, lo: np.ndarray, hi: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
        """[start, stop) indices whose coordinate lies in [lo - tol, hi + tol], clipped to the grid."""
        start = np.ceil((lo - tol) / self.delta + self.n / 2 - 0.5)
        stop = np.floor((hi + tol) / self.delta + self.n / 2 - 0.5) + 1
        return np.clip(start, 0, self.n).astype(np.int64), np.clip(stop, 0, self.n).astype(np.int64)


def tube_grid(radius: float, delta: float) -> TubeGrid:
    """Rows of tube centres within radius + delta of the axis (the bounding disk plus a margin)."""
    n = 2 * math.ceil(radius / delta)
    s = (np.arange(n) - n / 2 + 0.5) * delta
    positive_sq = s[n // 2:] ** 2  # increasing; the grid is symmetric about 0
    half = np.searchsorted(positive_sq, (radius + delta) ** 2 - s**2, side="right")
    return TubeGrid(delta=delta, first=n // 2 - half, stop=n // 2 + half)


def launch_offsets(radius: float, delta: float) -> np.ndarray:
    """All tube centres [M, 2] of ``tube_grid(radius, delta)`` in launch order (tests, small grids)."""
    grid = tube_grid(radius, delta)
    counts = grid.stop - grid.first
    rows = np.repeat(np.arange(grid.n), counts)
    cols = np.arange(len(rows)) - np.repeat(np.cumsum(counts) - counts, counts)  # position within the row
    return np.stack([grid.coordinate(rows), grid.coordinate(grid.first[rows] + cols)], axis=-1)


def _hull_points(vertices: np.ndarray) -> np.ndarray:
    """The convex-hull vertices (all vertices for a flat mesh): they bound every silhouette."""
    try:
        return vertices[scipy.spatial.ConvexHull(vertices).vertices]
    except scipy.spatial.QhullError:
        return vertices


def launch_windows(vertices: np.ndarray, u: np.ndarray) -> np.ndarray:
    """[D, 4] (lo1, hi1, lo2, hi2): the mesh's extent along theta-hat and phi-hat of each u.

    A ray whose centre lies outside this box cannot hit the mesh, so it is not launched; on a
    plate seen obliquely this removes most of the bounding disk.
    """
    points = _hull_points(vertices)
    out = np.empty((len(u), 4))
    step = max(1, HULL_VALUES // len(points))
    for s in range(0, len(u), step):
        for axis, basis in enumerate(polarisation_basis(u[s:s + step])):
            proj = basis @ points.T
            out[s:s + step, 2 * axis] = proj.min(axis=1)
            out[s:s + step, 2 * axis + 1] = proj.max(axis=1)
    return out


class RayTracer:
    """Embree scene of the facets (float32, local coordinates): first hits and occlusion."""

    def __init__(self, facets: FacetMesh):
        self.facets = facets
        self.normals = facets.normals
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, facets.vertices.astype(np.float32)[facets.faces])
        extent = np.ptp(facets.vertices, axis=0)
        self.offset = 1e-5 * float(np.linalg.norm(extent))

    def hit(self, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(facet index or -1, distance) of the first hit of each ray."""
        result = self.scene.run(origins.astype(np.float32), dirs.astype(np.float32), output=1)
        return result["primID"], result["tfar"].astype(np.float64)

    def clear(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """True where a ray from ``origins`` along ``dirs`` leaves the scene unblocked."""
        if len(origins) == 0:
            return np.zeros(0, dtype=bool)
        return self.scene.run(origins.astype(np.float32), dirs.astype(np.float32), query="OCCLUDED") != 0


@dataclass(frozen=True)
class Shot:
    """Everything a batch needs besides the Embree scene (sent once to each worker)."""

    u: np.ndarray  # [D, 3] directions toward the radar
    k: np.ndarray  # [N] wavenumbers
    tubes: TubeGrid  # tube centres in the launch plane (theta-hat, phi-hat)
    ranges: np.ndarray  # [D, 4] row start/stop, column start/stop of each direction's window
    ends: np.ndarray  # [D] flat index past each direction's last ray (cumulative ray counts)
    start: float  # launch plane distance R_s from the local origin
    first_bounce: int
    max_bounces: int
    channels: tuple  # (transmit, receive) per output channel, 0 = V (theta-hat), 1 = H (phi-hat)
    real_dtype: type

    @property
    def n_rays(self) -> int:
        return int(self.ends[-1]) if len(self.ends) else 0

    @property
    def delta(self) -> float:
        return self.tubes.delta


def _row_widths(tubes: TubeGrid, ranges: np.ndarray) -> np.ndarray:
    """[D, n] rays of each grid row inside each direction's window (0 outside its row range)."""
    row = np.arange(tubes.n)
    width = np.minimum(tubes.stop, ranges[:, 3, None]) - np.maximum(tubes.first, ranges[:, 2, None])
    width[(row < ranges[:, 0, None]) | (row >= ranges[:, 1, None])] = 0
    return np.maximum(width, 0)


def ray_counts(tubes: TubeGrid, ranges: np.ndarray) -> np.ndarray:
    """Rays launched per direction: the disk's tubes inside the direction's window."""
    counts = np.empty(len(ranges), dtype=np.int64)
    step = max(1, CELLS_PER_BATCH // tubes.n)
    for s in range(0, len(ranges), step):
        counts[s:s + step] = _row_widths(tubes, ranges[s:s + step]).sum(axis=1)
    return counts


def plan_batches(ends: np.ndarray, n_rows: int, n_freq: int, rays_per_batch: int) -> list[tuple[int, int]]:
    """Flat ray ranges [start, stop) of the (direction, row, column) order, each <= rays_per_batch.

    ``n_freq`` counts output values per direction (frequencies x polarisation channels).
    A batch also spans at most as many directions as keep its partial sum [dirs, N] within
    VALUES_PER_CHUNK values and its row table [dirs, n_rows] within CELLS_PER_BATCH, so every
    array of a batch stays bounded however small the per-direction grids are.
    """
    max_dirs = max(1, min(VALUES_PER_CHUNK // max(n_freq, 1), CELLS_PER_BATCH // max(n_rows, 1)))
    total = int(ends[-1]) if len(ends) else 0
    plan, start = [], 0
    while start < total:
        first = int(np.searchsorted(ends, start, side="right"))
        stop = min(start + rays_per_batch, total, int(ends[min(first + max_dirs, len(ends)) - 1]))
        plan.append((start, stop))
        start = stop
    return plan


def memory_bound(rays_per_batch: int, n_freq: int) -> int:
    """Upper bound (bytes) on one batch's array memory, whatever the ray density or bounce count.

    Per worker; the Embree scene (proportional to the facets) and the [D, N] output come on top.
    """
    return (BYTES_PER_RAY * rays_per_batch + BYTES_PER_VALUE * min(rays_per_batch * n_freq, VALUES_PER_CHUNK)
            + BYTES_PER_CELL * CELLS_PER_BATCH)


def _launch(shot: Shot, start: int, stop: int):
    """Rays start..stop of the flat order: (d, s1, s2, lo, hi), tube centre (s1, s2) of each ray.

    The batch holds directions lo..hi-1; ``d`` (relative to lo, non-decreasing) is each ray's
    direction. The flat order runs over directions, then grid rows, then columns, inside each
    direction's window.
    """
    lo = int(np.searchsorted(shot.ends, start, side="right"))
    hi = int(np.searchsorted(shot.ends, stop - 1, side="right")) + 1
    widths = _row_widths(shot.tubes, shot.ranges[lo:hi]).ravel()
    cell_end = np.cumsum(widths) + (shot.ends[lo - 1] if lo > 0 else 0)
    flat = np.arange(start, stop)
    cell = np.searchsorted(cell_end, flat, side="right")
    d, row = np.divmod(cell, shot.tubes.n)
    col = np.maximum(shot.tubes.first[row], shot.ranges[lo + d, 2]) + (flat - cell_end[cell] + widths[cell])
    return d, shot.tubes.coordinate(row), shot.tubes.coordinate(col), lo, hi


# Rows of the packed ray state [13, R]: position, direction D, tube axes a1 and a2, path L.
# Component-major, so every update runs over contiguous rays (an [R, 3] layout makes numpy loop
# over rays with inner loops of length 3, several times slower). The field is not stored: it
# starts as a1 (V) or a2 (H), and E' = -E + 2 (n.E) n is minus the reflection that a1 and a2
# get, so after b reflections E = (-1)^b a_transmit.
_POS, _DIR, _A1, _A2, _PATH = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), 12
_VECTORS = slice(3, 12)  # D, a1, a2: reflected together


def _dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of [3, R] arrays."""
    out = a[0] * b[0]
    out += a[1] * b[1]
    out += a[2] * b[2]
    return out


def _rays(v: np.ndarray) -> np.ndarray:
    """[3, R] float64 -> [R, 3] contiguous float32 for Embree."""
    return np.ascontiguousarray(v.T, dtype=np.float32)


def _initial_state(shot: Shot, u: np.ndarray, theta: np.ndarray, phi: np.ndarray, d_idx: np.ndarray,
                   s1: np.ndarray, s2: np.ndarray) -> np.ndarray:
    """[13, R]: D = -u, a1 = theta-hat, a2 = phi-hat of each ray's direction, launch point, L = 0.

    Rays come grouped by direction (``d_idx`` non-decreasing), so the per-direction vectors
    are repeated rather than gathered. Launch point: R_s u + s1 theta-hat + s2 phi-hat.
    """
    table = np.concatenate([-u.T, theta.T, phi.T], axis=0)  # [9, n] per direction
    state = np.empty((13, len(d_idx)))
    state[_VECTORS] = np.repeat(table, np.bincount(d_idx, minlength=len(u)), axis=1)
    np.multiply(state[_DIR], -shot.start, out=state[_POS])
    state[_POS] += s1 * state[_A1]
    state[_POS] += s2 * state[_A2]
    state[_PATH] = 0.0
    return state


def shoot(shot: Shot, tracer: RayTracer, start: int, stop: int) -> tuple[int, np.ndarray]:
    """(first direction, partial sum [n, N]) of rays start..stop: hits first_bounce..max_bounces.

    The partial sum lacks the common factor -jk/sqrt(pi). Contributions are summed after each
    bounce, so the batch's memory is a few arrays of its ray count whatever max_bounces is.
    The ray state is one [13, R] array, so dropping the rays that leave costs one gather.
    """
    d_idx, s1, s2, lo, hi = _launch(shot, start, stop)
    u = shot.u[lo:hi]
    theta, phi = polarisation_basis(u)
    state = _initial_state(shot, u, theta, phi, d_idx, s1, s2)
    del s1, s2
    u_rows, basis = np.ascontiguousarray(u.T), (np.ascontiguousarray(theta.T), np.ascontiguousarray(phi.T))
    out = np.zeros((len(u), len(shot.k), len(shot.channels)), dtype=po.complex_dtype(shot.real_dtype))
    normals = np.ascontiguousarray(tracer.normals.T)
    for bounce in range(1, shot.max_bounces + 1):
        if len(d_idx) == 0:
            break
        facet, dist = tracer.hit(_rays(state[_POS]), _rays(state[_DIR]))
        live = facet >= 0
        if not live.all():
            state, d_idx, facet, dist = state[:, live], d_idx[live], facet[live], dist[live]
        state[_POS] += dist * state[_DIR]  # the hit point
        state[_PATH] += dist
        normal = np.take(normals, facet, axis=1)
        cos_in = _dot3(normal, state[_DIR])
        normal *= -np.sign(cos_in)  # toward the incoming ray: n.D < 0
        cos_in = -np.abs(cos_in)
        if bounce >= shot.first_bounce:
            sign = -1.0 if (bounce - 1) % 2 else 1.0  # E incident on hit b has had b - 1 reflections
            terms = _contributions(tracer, u_rows, basis, shot.channels, d_idx, state, sign, normal, cos_in,
                                   shot.delta, shot.start)
            _accumulate(out, terms, shot.k, shot.real_dtype)
        if bounce == shot.max_bounces:
            break
        # PEC: v' = v - 2 (v.n) n for D and the tube axes (the field follows a_transmit)
        vectors = state[_VECTORS].reshape(3, 3, -1)
        twice = vectors[:, 0] * normal[0]
        twice += vectors[:, 1] * normal[1]
        twice += vectors[:, 2] * normal[2]
        twice *= 2.0
        for j in range(3):
            vectors[:, j] -= twice * normal[j]
        # restart just off the surface on the lit side; count the offset's share along D' in L
        state[_POS] += tracer.offset * normal
        state[_PATH] += tracer.offset * _dot3(normal, state[_DIR])
    return lo, out


def _contributions(tracer, u_rows, basis, channels, d_idx, state, sign, normal, cos_in, delta, start):
    """Exit-ray terms of the hits seen from the radar (occlusion ray toward u from the lit side).

    ``u_rows`` and ``basis`` (theta-hat, phi-hat) are [3, n] per direction. The ray geometry
    does not depend on the polarisation: each channel only changes E = sign * a_transmit and
    e_r, so one trace gives every channel's amplitude ("amp" [channels, R]).
    """
    seen = tracer.clear(_rays(state[_POS] + tracer.offset * normal), _rays(np.take(u_rows, d_idx, axis=1)))
    seen &= np.abs(cos_in) > GRAZING  # a grazing tube's footprint (delta^2 / |n.D|) is unbounded
    d_idx, state, normal, cos_in = d_idx[seen], state[:, seen], normal[:, seen], cos_in[seen]
    uu, dirs = np.take(u_rows, d_idx, axis=1), state[_DIR]
    area = (sign * delta**2) / np.abs(cos_in)
    amp = np.empty((len(channels), len(d_idx)))
    for i, (transmit, receive) in enumerate(channels):
        field, e_r = state[(_A1, _A2)[transmit]], np.take(basis[receive], d_idx, axis=1)
        # e_r . [D (n.E) - E (n.D)] * footprint area delta^2 / |n.D|, with E = sign * a_transmit
        amp[i] = _dot3(e_r, dirs) * _dot3(normal, field) - _dot3(e_r, field) * cos_in
        amp[i] *= area
    # footprint edge b = a - D (a.n)/(D.n); the phase w.r (w = u - D) varies along it by w.b
    w = uu - dirs
    w_dir = _dot3(w, dirs) / cos_in
    c = [0.5 * delta * (_dot3(w, state[rows]) - w_dir * _dot3(state[rows], normal)) for rows in (_A1, _A2)]
    return {"dir": d_idx, "amp": amp, "phase": _dot3(uu, state[_POS]) + start - state[_PATH],
            "c1": c[0], "c2": c[1]}


def _sinc(x: np.ndarray) -> np.ndarray:
    """sin(x) / x in x's precision (1 at 0); the footprint arguments |x| stay below a few pi."""
    out = np.sin(x)
    np.divide(out, x, out=out, where=x != 0)
    out[x == 0] = 1.0
    return out


def _accumulate(out: np.ndarray, terms: dict[str, np.ndarray], k: np.ndarray, real_dtype) -> None:
    """out[d, n, c] += sum over terms of amp_c sinc(k c1) sinc(k c2) exp(jk phase) (without -jk/sqrt(pi)).

    The phase and footprint factors are shared by the channels; only the amplitude differs.
    """
    step = max(1, VALUES_PER_CHUNK // len(k))
    uniform = len(k) < 3 or np.allclose(np.diff(k), k[1] - k[0], rtol=1e-9, atol=0)
    k_real = k.astype(real_dtype)
    for s in range(0, len(terms["dir"]), step):
        sl = slice(s, s + step)
        phase = terms["phase"][sl]
        values = po.entry_phases(phase, k, real_dtype) if uniform else po.cis(np.outer(phase, k), real_dtype)
        footprint = _sinc(np.outer(terms["c1"][sl], k_real))
        footprint *= _sinc(np.outer(terms["c2"][sl], k_real))
        values *= footprint
        rows = terms["dir"][sl]
        select = scipy.sparse.csc_array((np.ones(len(rows), dtype=real_dtype), rows, np.arange(len(rows) + 1)),
                                        shape=(len(out), len(rows)))
        for c, amp in enumerate(terms["amp"][:, sl]):
            weighted = values * amp.astype(real_dtype)[:, None]
            out[:, :, c] += (select @ weighted.view(real_dtype)).view(values.dtype)


_WORKER: dict = {}  # in a worker process: the current call's token, Shot and Embree scene
_POOL: list = []  # in the parent: [(workers, executor)], kept between calls
_POOL_LOCK = threading.Lock()


def _worker_batch(path: str, token: str, batch: tuple[int, int]) -> tuple[int, np.ndarray]:
    """One batch in a worker; the call's scene is built on the worker's first batch of that call."""
    if _WORKER.get("token") != token:
        _WORKER.clear()
        with open(path, "rb") as handle:
            facets, shot = pickle.load(handle)
        _WORKER.update(token=token, shot=shot, tracer=RayTracer(facets))
    return shoot(_WORKER["shot"], _WORKER["tracer"], *batch)


def _context():
    """forkserver where available: a clean, single-threaded parent for the workers.

    Forking the caller directly would copy Embree's TBB pool and any torch/BLAS threads in a
    state that can deadlock the child; spawn works everywhere but re-imports per worker.
    """
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["radar2shape.radar.sbr"])
        return ctx
    return multiprocessing.get_context("spawn")


def _executor(workers: int) -> ProcessPoolExecutor:
    """The kept pool of ``workers`` processes (made on first use: start-up costs ~1 s per worker)."""
    with _POOL_LOCK:
        if _POOL and _POOL[0][0] == workers and not getattr(_POOL[0][1], "_broken", False):
            return _POOL[0][1]
        _shutdown_locked()
        pool = ProcessPoolExecutor(workers, mp_context=_context())
        _POOL.append((workers, pool))
        return pool


def _shutdown_locked(wait: bool = True) -> None:
    while _POOL:
        _POOL.pop()[1].shutdown(wait=wait, cancel_futures=True)


def shutdown_workers() -> None:
    """Stop the SBR worker processes kept between calls (they also end with the interpreter)."""
    with _POOL_LOCK:
        _shutdown_locked()


def map_batches(function, tasks: list, workers: int):
    """Yield ``function(*task)`` in task order from ``workers`` processes (kept between calls).

    A task that raises, or a worker that dies (killed by the out-of-memory killer, crashed, or
    failed to start), stops the run with one SBRWorkerError in the parent; the call's queued
    tasks are cancelled, and a broken pool is replaced on the next call.
    """
    pool = _executor(workers)
    futures = []
    try:
        futures = [pool.submit(function, *task) for task in tasks]
        for i, future in enumerate(futures):
            try:
                result = future.result()
            except (BrokenProcessPool, OSError) as err:
                with _POOL_LOCK:
                    if _POOL and _POOL[0][1] is pool:
                        _shutdown_locked(wait=False)
                raise SBRWorkerError(
                    f"an SBR worker process died at batch {i + 1} of {len(tasks)} (killed, e.g. out of memory, "
                    f"crashed, or failed to start: a script that runs the simulator needs the "
                    f"`if __name__ == \"__main__\":` guard); retry with fewer workers or a smaller "
                    f"rays_per_batch ({type(err).__name__}: {err})") from err
            except Exception as err:
                raise SBRWorkerError(f"SBR batch {i + 1} of {len(tasks)} failed in a worker process: "
                                     f"{type(err).__name__}: {err}") from err
            yield result
    finally:
        for future in futures:
            future.cancel()


@contextmanager
def _call_file(facets: FacetMesh, shot: Shot):
    """A temporary pickle of the call's scene and Shot that the workers read once each."""
    fd, path = tempfile.mkstemp(prefix="radar2shape-sbr-", suffix=".pkl")
    try:
        with os.fdopen(fd, "wb") as handle:
            pickle.dump((facets, shot), handle, protocol=pickle.HIGHEST_PROTOCOL)
        yield path
    finally:
        os.unlink(path)


def prepare(facets: FacetMesh, u: np.ndarray, k: np.ndarray, max_bounces: int, rays_per_wavelength: float,
            real_dtype, first_bounce: int, polarization: str) -> Shot:
    """The Shot of one multibounce call: tube grid, launch windows, ray counts and polarisation."""
    channels, _ = check_channels(polarization)
    delta = 2.0 * math.pi / float(np.max(k)) / rays_per_wavelength
    radius = float(np.linalg.norm(facets.vertices, axis=1).max())
    extent = np.ptp(facets.vertices, axis=0)
    u = np.ascontiguousarray(u, dtype=np.float64)
    tubes = tube_grid(radius, delta)
    windows = launch_windows(facets.vertices, u)
    tol = WINDOW_TOL * radius
    ranges = np.concatenate([np.stack(tubes.index_range(windows[:, 0], windows[:, 1], tol), axis=1),
                             np.stack(tubes.index_range(windows[:, 2], windows[:, 3], tol), axis=1)], axis=1)
    return Shot(u=u, k=np.asarray(k, dtype=np.float64), tubes=tubes, ranges=ranges,
                ends=np.cumsum(ray_counts(tubes, ranges)), start=1.01 * radius + 1e-5 * float(np.linalg.norm(extent)),
                first_bounce=first_bounce, max_bounces=max_bounces, channels=channels,
                real_dtype=real_dtype)


def multibounce(facets: FacetMesh, u: np.ndarray, k: np.ndarray, max_bounces: int = DEFAULT_BOUNCES,
                rays_per_wavelength: float = DEFAULT_RAYS_PER_WAVELENGTH, real_dtype=np.float32,
                first_bounce: int = 2, tracer: RayTracer | None = None, polarization: str = "VV",
                workers: int | None = None, rays_per_batch: int = DEFAULT_RAYS_PER_BATCH) -> np.ndarray:
    """Ray-sum response [D, N] of hits first_bounce..max_bounces (local-origin phase), |S|^2 in m^2.

    ``polarization`` "VV" (theta-hat transmit and receive), "HH" (phi-hat), "HV" (transmit H,
    receive V) or "VH": first letter transmit, second receive (backscatter alignment: one
    theta-hat/phi-hat frame of u for both). A list of names gives [D, N, len(list)] from one
    ray trace (the rays do not depend on the polarisation). ``workers`` processes trace the
    batches (None: the usable cores, or torch's thread count when torch is loaded; 1: in this
    process). ``rays_per_batch`` launched rays per batch bounds each worker's memory
    (memory_bound, docs/sbr_lora.md). ``first_bounce=1`` gives the pure-SBR response including
    the single bounce (used to check the normalisation against PO); the hybrid uses 2.
    """
    max_bounces, rays_per_wavelength = check_options(max_bounces, rays_per_wavelength)
    rays_per_batch = _positive_int(rays_per_batch, "rays_per_batch")
    workers = default_workers() if workers is None else _positive_int(workers, "workers")
    channels, stacked = check_channels(polarization)
    out = np.zeros((len(u), len(k), len(channels)), dtype=po.complex_dtype(real_dtype))
    if max_bounces >= first_bounce and len(u) > 0:
        shot = prepare(facets, u, k, max_bounces, rays_per_wavelength, real_dtype, first_bounce, polarization)
        batches = plan_batches(shot.ends, shot.tubes.n, len(k) * len(channels), rays_per_batch)
        for lo, part in _run_batches(facets, shot, batches, min(workers, len(batches)), tracer):
            out[lo:lo + len(part)] += part
        out *= (-1j * k / _SQRT_PI).astype(out.dtype)[:, None]
    return out if stacked else out[..., 0]


def _run_batches(facets: FacetMesh, shot: Shot, batches: list, workers: int, tracer: RayTracer | None):
    """(first direction, partial sum) of each batch in plan order: in worker processes, or here for one."""
    if workers > 1:
        with _call_file(facets, shot) as path:
            token = uuid.uuid4().hex
            yield from map_batches(_worker_batch, [(path, token, b) for b in batches], workers)
    else:
        tracer = tracer or RayTracer(facets)
        yield from (shoot(shot, tracer, *batch) for batch in batches)
