"""Shooting and bouncing rays (Ling, Chou & Lee 1989) for the multi-bounce part of the response.

The simulator's ``method="sbr"`` is a hybrid: exact facet PO (with shadowing) for the first
bounce, plus :func:`multibounce` here for bounces 2..max_bounces. Derivation and checks in
docs/sbr_lora.md. Per direction u, square ray tubes of side ``delta`` (``lambda_min /
rays_per_wavelength``) leave a plane just outside the bounding sphere toward -u and carry a real
field vector E (the incident polarisation, theta-hat of u) and a path length L. At each hit
(PEC): D' = D - 2 (D.n) n, E' = -E + 2 (n.E) n. From the second hit on, each hit radiates back
toward u with the PO integral over its tube footprint (n oriented toward the incoming ray):

    S_ray = -j k/sqrt(pi) * e_r.[D (n.E) - E (n.D)] * delta^2/|n.D| * sinc(k c1) sinc(k c2)
            * exp(jk (u.r + R_s - L)),

where e_r = e (co-polarised receive), c_i = delta w.b_i / 2 with w = u - D and b_i the tube's
cross-section axes projected along D onto the facet plane. With one bounce this is PO
(|S|^2 = RCS in m^2, phase referenced to the local origin), which the tests check on a plate.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

from radar2shape.errors import UserInputError
from radar2shape.radar import po
from radar2shape.radar.facets import FacetMesh

DEFAULT_BOUNCES = 5
DEFAULT_RAYS_PER_WAVELENGTH = 8.0
RAYS_PER_CHUNK = 2**19  # rays traced per Embree call (several directions share one call)
VALUES_PER_CHUNK = 2**21  # ray x frequency values evaluated at once when summing contributions
GRAZING = 1e-6  # hits with |n.D| below this add nothing (degenerate footprint)
_SQRT_PI = math.sqrt(math.pi)


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


def polarisation(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta-hat, phi-hat) of each direction [D, 3]; at the poles the roll angle is taken as 0."""
    aspect = np.arccos(np.clip(u[:, 2], -1.0, 1.0))
    roll = np.arctan2(u[:, 1], u[:, 0])
    theta = np.stack([np.cos(aspect) * np.cos(roll), np.cos(aspect) * np.sin(roll), -np.sin(aspect)], axis=-1)
    phi = np.stack([-np.sin(roll), np.cos(roll), np.zeros_like(roll)], axis=-1)
    return theta, phi


def launch_offsets(radius: float, delta: float) -> np.ndarray:
    """Tube centres [M, 2] on a square grid of step delta covering the disk of ``radius``.

    Centres sit at half-integer multiples of delta, so a plate edge through the origin falls
    between tubes rather than on a row of them.
    """
    n = 2 * math.ceil(radius / delta)
    s = (np.arange(n) - n / 2 + 0.5) * delta
    s1, s2 = np.meshgrid(s, s, indexing="ij")
    keep = s1**2 + s2**2 <= (radius + delta) ** 2
    return np.stack([s1[keep], s2[keep]], axis=-1)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _reflect(v: np.ndarray, n: np.ndarray) -> np.ndarray:
    return v - 2.0 * _dot(v, n)[:, None] * n


class RayTracer:
    """Embree scene of the facets (float32, local coordinates): first hits and occlusion."""

    def __init__(self, facets: FacetMesh):
        self.facets = facets
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, facets.vertices.astype(np.float32)[facets.faces])
        extent = np.ptp(facets.vertices, axis=0)
        self.offset = 1e-5 * float(np.linalg.norm(extent))

    def hit(self, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(facet index or -1, distance) of the first hit of each ray."""
        result = self.scene.run(origins.astype(np.float32), dirs.astype(np.float32), output=1)
        return result["primID"].astype(np.int64), result["tfar"].astype(np.float64)

    def clear(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """True where a ray from ``origins`` along ``dirs`` leaves the scene unblocked."""
        if len(origins) == 0:
            return np.zeros(0, dtype=bool)
        return self.scene.run(origins.astype(np.float32), dirs.astype(np.float32), query="OCCLUDED") != 0


def _trace_chunk(tracer: RayTracer, u: np.ndarray, offsets: np.ndarray, delta: float, radius: float,
                 first_bounce: int, max_bounces: int) -> dict[str, np.ndarray]:
    """Contributions of hits first_bounce..max_bounces for the directions ``u`` [D, 3].

    Returns per contributing hit: dir (direction index), amp (frequency-free amplitude),
    phase (metres: the term goes as exp(jk phase)) and c1, c2 (footprint sinc arguments / k).
    """
    theta, phi = polarisation(u)
    n_dir, n_off = len(u), len(offsets)
    d_idx = np.repeat(np.arange(n_dir), n_off)
    start = 1.01 * radius + tracer.offset
    origins = (start * u[:, None, :] + offsets[None, :, 0, None] * theta[:, None, :]
               + offsets[None, :, 1, None] * phi[:, None, :]).reshape(-1, 3)
    dirs = -u[d_idx]
    field = theta[d_idx].copy()  # E: incident polarisation, real (PEC keeps it real)
    axes = (theta[d_idx].copy(), phi[d_idx].copy())  # tube cross-section axes, reflected along
    path = np.zeros(len(d_idx))  # L: metres travelled from the launch plane
    point = origins
    parts = []
    for bounce in range(1, max_bounces + 1):
        facet, dist = tracer.hit(point, dirs)
        live = facet >= 0
        d_idx, facet, dist, dirs, field, path, point = (
            a[live] for a in (d_idx, facet, dist, dirs, field, path, point))
        axes = tuple(a[live] for a in axes)
        if len(d_idx) == 0:
            break
        hit = point + dist[:, None] * dirs
        path = path + dist
        normal = tracer.facets.normals[facet]
        cos_in = _dot(normal, dirs)
        normal = normal * -np.sign(cos_in)[:, None]  # toward the incoming ray: n.D < 0
        cos_in = -np.abs(cos_in)
        if bounce >= first_bounce:
            parts.append(_contributions(tracer, u, theta, d_idx, hit, dirs, normal, cos_in, field, axes, path,
                                        delta, start))
        if bounce == max_bounces:
            break
        field = -field + 2.0 * _dot(normal, field)[:, None] * normal
        axes = tuple(_reflect(a, normal) for a in axes)
        dirs = _reflect(dirs, normal)
        # restart just off the surface on the lit side; count the offset's share along D' in L
        point = hit + tracer.offset * normal
        path = path + tracer.offset * _dot(normal, dirs)
    keys = ("dir", "amp", "phase", "c1", "c2")
    if not parts:
        return {key: np.zeros(0, dtype=np.int64 if key == "dir" else np.float64) for key in keys}
    return {key: np.concatenate([p[key] for p in parts]) for key in keys}


def _contributions(tracer, u, theta, d_idx, hit, dirs, normal, cos_in, field, axes, path, delta, start):
    """Exit-ray terms of the hits seen from the radar (occlusion ray toward u from the lit side)."""
    uu = u[d_idx]
    seen = tracer.clear(hit + tracer.offset * normal, uu)
    seen &= np.abs(cos_in) > GRAZING  # a grazing tube's footprint (delta^2 / |n.D|) is unbounded
    d_idx, hit, dirs, normal, cos_in, field, path, uu = (
        a[seen] for a in (d_idx, hit, dirs, normal, cos_in, field, path, uu))
    axes = tuple(a[seen] for a in axes)
    receive = theta[d_idx]
    # e_r . [D (n.E) - E (n.D)] * footprint area delta^2 / |n.D|
    current = _dot(receive, dirs) * _dot(normal, field) - _dot(receive, field) * cos_in
    amp = current * delta**2 / np.abs(cos_in)
    w = uu - dirs
    c = []
    for a in axes:  # footprint edge b = a - D (a.n)/(D.n); the phase w.r varies along it
        b = a - dirs * (_dot(a, normal) / cos_in)[:, None]
        c.append(0.5 * delta * _dot(w, b))
    return {"dir": d_idx, "amp": amp, "phase": _dot(uu, hit) + start - path, "c1": c[0], "c2": c[1]}


def _accumulate(out: np.ndarray, terms: dict[str, np.ndarray], k: np.ndarray, real_dtype) -> None:
    """out[d, n] += sum over terms of amp sinc(k c1) sinc(k c2) exp(jk phase) (without -jk/sqrt(pi))."""
    step = max(1, VALUES_PER_CHUNK // len(k))
    uniform = len(k) < 3 or np.allclose(np.diff(k), k[1] - k[0], rtol=1e-9, atol=0)
    for s in range(0, len(terms["dir"]), step):
        sl = slice(s, s + step)
        phase = terms["phase"][sl]
        values = po.entry_phases(phase, k, real_dtype) if uniform else po.cis(np.outer(phase, k), real_dtype)
        amp = terms["amp"][sl, None] * np.sinc(np.outer(terms["c1"][sl], k) / np.pi)
        amp *= np.sinc(np.outer(terms["c2"][sl], k) / np.pi)
        values *= amp.astype(real_dtype)
        rows = terms["dir"][sl]
        select = scipy.sparse.csc_array((np.ones(len(rows), dtype=real_dtype), rows, np.arange(len(rows) + 1)),
                                        shape=(len(out), len(rows)))
        out += (select @ values.view(real_dtype)).view(values.dtype)


def multibounce(facets: FacetMesh, u: np.ndarray, k: np.ndarray, max_bounces: int = DEFAULT_BOUNCES,
                rays_per_wavelength: float = DEFAULT_RAYS_PER_WAVELENGTH, real_dtype=np.float32,
                first_bounce: int = 2, tracer: RayTracer | None = None) -> np.ndarray:
    """Ray-sum response [D, N] of hits first_bounce..max_bounces (local-origin phase), |S|^2 in m^2.

    ``first_bounce=1`` gives the pure-SBR response including the single bounce (used to check
    the normalisation against PO); the simulator's hybrid uses the default 2.
    """
    max_bounces, rays_per_wavelength = check_options(max_bounces, rays_per_wavelength)
    out = np.zeros((len(u), len(k)), dtype=po.complex_dtype(real_dtype))
    if max_bounces < first_bounce:
        return out
    tracer = tracer or RayTracer(facets)
    delta = 2.0 * math.pi / float(np.max(k)) / rays_per_wavelength
    radius = float(np.linalg.norm(facets.vertices, axis=1).max())
    offsets = launch_offsets(radius, delta)
    per_chunk = max(1, RAYS_PER_CHUNK // len(offsets))
    for s in range(0, len(u), per_chunk):
        terms = _trace_chunk(tracer, u[s:s + per_chunk], offsets, delta, radius, first_bounce, max_bounces)
        part = out[s:s + per_chunk]
        _accumulate(part, terms, k, real_dtype)
    out *= (-1j * k / _SQRT_PI).astype(out.dtype)
    return out
