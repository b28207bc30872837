"""Equivalent edge currents on top of facet PO: the diffraction of a mesh's sharp edges.

PO integrates the physical-optics current of every lit facet, so each face of a wedge already
contributes its own "edge term" (the endpoint of its phase integral). What PO misses is the
fringe: the exact wedge's diffraction (Keller's coefficient) minus those PO edge terms. Written
as equivalent electric and magnetic line currents along each sharp edge (Michaeli's fringe
currents evaluated on the monostatic Keller cone), the fringe adds to PO, for a straight edge of
length L, midpoint c and unit tangent t, seen from u (derivation and checks in docs/radar.md):

    S_pq += L / (2 sqrt(pi)) [f_s(phi) (p.t^)(q.t^) - f_h(phi) (p.w^)(q.w^)] exp(2jk u.c) sinc(k L u.t)

where t^ is t projected perpendicular to u and normalised, w^ = t x u / |t x u|, p, q the receive
and transmit unit vectors (theta-hat or phi-hat of u), phi the angle of u around the edge
measured from face 0 through the outside, and f_s, f_h the dimensionless soft (E along the edge)
and hard (H along the edge) fringe coefficients. The sinc is the exact integral of the linear
phase along the edge, so everything is vectorised over edges, directions and frequencies.

Sharp edges: two faces whose normals turn by at least ``threshold_deg`` (default 30 deg), plus
open boundary edges (one face: a half-plane). Rounded edges: at wavenumber k, a convex edge whose
radius of curvature across it (read through the two opposite vertices) is at most ``krho`` / k
(default 1: under a radian of phase per radius, a rim the wave cannot resolve) also carries its
fringe current, at that frequency only. Edges of more than two
faces (the diagonal of a double-sided plate, T-junctions) and concave edges (outside wedge angle
below pi, where multiple reflections rule: SBR's part) carry no fringe current. With ``order`` 2
(the default) the facing edges of flat sheets also exchange the wave one sends along the sheet to
the other (double diffraction, radar/edge_pairs.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
import scipy.sparse

from radar2shape.errors import UserInputError
from radar2shape.radar import po
from radar2shape.radar.facets import FacetMesh

# Normal turn (deg) from which an edge between two faces is sharp: any surface whose normals
# turn by less than 30 deg from facet to facet (at least 12 facets per full turn) counts as
# smooth and carries no fringe current, whose sum there would be a faceting artefact
# (docs/radar.md, "Which edges").
SHARP_EDGE_DEG = 30.0
# k rho below which a smoothly rounded convex edge diffracts like a wedge: a rim of radius rho <
# lambda / (2 pi) is not resolved by the wave. The fringe terms of the many small turns across such
# a rim sum to a mesh-independent value as the mesh is refined (docs/radar.md, "Rounded edges").
ROUNDED_EDGE_KRHO = 1.0
# Diffraction order: 2 adds the wave between the facing edges of flat sheets (radar/edge_pairs.py),
# which sets a plate's HH apart from its VV; closed solids have no sheet edges, so 1 and 2 agree there.
EDGE_ORDER = 2
# Polarisation letters: V = theta-hat of u, H = phi-hat. First letter transmit, second receive.
POLARIZATIONS = ("VV", "HH", "HV", "VH")
ALL_POLARIZATIONS = ("VV", "VH", "HV", "HH")  # reshape(..., 2, 2) -> [transmit, receive], V = 0, H = 1
_BASIS = {"V": 0, "H": 1}
# Half-width (rad) of the interval around a face's specular direction where the fringe, a
# difference of two poles with the same residue, is interpolated between its two ends.
REFLECTION_GAP = 1e-3
# Angular slack (rad) for rounding: directions this close to a face plane count as grazing.
ANGLE_TOL = 1e-9
# Edge-visibility rays start this fraction of the bbox diagonal off the edge, in the outside
# wedge, at least RAY_MARGIN of the outside angle away from either face (so grazing rays clear it).
EDGE_RAY_OFFSET = 1e-4
RAY_MARGIN = 0.05
# (edge, direction) pairs whose sinc argument k_min L |u.t| is below this are summed per entry
# (exact sinc); above it the sinc splits into two exponentials, which then lose under 1 digit.
TAU_SINC = 0.5
ENTRY_VALUES = 2**20
_SQRT_PI = math.sqrt(math.pi)


@dataclass(frozen=True)
class EdgeSet:
    """The sharp edges of a mesh as wedges (local coordinates, like the FacetMesh they come from)."""

    centres: np.ndarray  # [E, 3] edge midpoints
    tangents: np.ndarray  # [E, 3] unit tangents
    lengths: np.ndarray  # [E]
    inward0: np.ndarray  # [E, 3] unit vector in face 0, perpendicular to the edge, pointing into the face
    normal0: np.ndarray  # [E, 3] outward unit normal of face 0
    wedge: np.ndarray  # [E] outside wedge angle / pi, in [1, 2] (2: half-plane)
    faces: np.ndarray  # [E, 2] facet indices (face 1 = face 0 for a one-sided boundary edge)
    one_sided: np.ndarray  # [E] bool: boundary of a one-sided sheet, lit (like its PO) from face 0's side only
    radius: np.ndarray  # [E] radius of curvature across a rounded edge (m); 0 for sharp and boundary edges

    @property
    def n_edges(self) -> int:
        return len(self.lengths)

    def subset(self, keep: np.ndarray) -> "EdgeSet":
        """The edges selected by a boolean mask or index array."""
        return EdgeSet(**{f.name: getattr(self, f.name)[keep] for f in fields(self)})


def check_threshold(threshold_deg) -> float:
    """A sharp-edge threshold in degrees, within (0, 180]."""
    try:
        value = float(threshold_deg)
    except (TypeError, ValueError):
        raise UserInputError(f"edge_threshold_deg: expected degrees in (0, 180], got {threshold_deg!r}") from None
    if not (0.0 < value <= 180.0):
        raise UserInputError(f"edge_threshold_deg: expected degrees in (0, 180], got {threshold_deg!r}")
    return value


def check_order(order) -> int:
    """The diffraction order of the edge terms: 1 (single) or 2 (plus sheet edge pairs)."""
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order not in (1, 2):
        raise UserInputError(f"edge_order: expected 1 (single diffraction) or 2 (plus the double diffraction "
                             f"between facing sheet edges), got {order!r}")
    return int(order)


def check_krho(krho) -> float:
    """The rounded-edge limit k rho, >= 0 (0: only edges sharp by the normal-turn threshold)."""
    try:
        value = float(krho)
    except (TypeError, ValueError):
        raise UserInputError(f"edge_krho: expected a number >= 0, got {krho!r}") from None
    if not (np.isfinite(value) and value >= 0.0):
        raise UserInputError(f"edge_krho: expected a number >= 0, got {krho!r}")
    return value


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _edge_faces(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unique undirected edges [U, 2] (sorted vertex pairs), face count per edge, and the first
    two faces of each edge [U, 2] (-1 where absent)."""
    pairs = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)  # [3F, 2] directed
    face_of = np.repeat(np.arange(len(faces)), 3)
    key = np.sort(pairs, axis=1)
    unique, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    order = np.argsort(inverse, kind="stable")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    first = face_of[order[starts]]
    second = np.where(counts > 1, face_of[order[np.minimum(starts + 1, len(order) - 1)]], -1)
    return unique, counts, np.stack([first, second], axis=1)


def _hinge_radius(facets: FacetMesh, unique: np.ndarray, pair: np.ndarray, tangents: np.ndarray,
                  turn: np.ndarray) -> np.ndarray:
    """Radius of the circle through the edge and the two opposite vertices, seen along the edge:
    |P0 - P1| / (2 sin turn) with P0, P1 the opposite vertices projected across the edge. Exact
    for a strip of a cylinder (any triangulation of its quads); on a sphere, whose edges sit inside
    it by their sag, it reads 1.5 x the radius (so it errs toward fewer rounded edges)."""
    opposite = facets.faces[pair].sum(axis=2) - unique.sum(axis=1)[:, None]  # [U, 2] vertex ids
    chord = facets.vertices[opposite[:, 1]] - facets.vertices[opposite[:, 0]]
    chord -= np.einsum("ij,ij->i", chord, tangents)[:, None] * tangents
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(turn > ANGLE_TOL, np.linalg.norm(chord, axis=1) / (2.0 * np.sin(turn)), np.inf)


def sharp_edges(facets: FacetMesh, threshold_deg: float = SHARP_EDGE_DEG, max_radius: float = 0.0) -> EdgeSet:
    """The mesh's convex sharp edges, open boundary edges and (with ``max_radius`` > 0) the convex
    rounded edges of radius of curvature at most ``max_radius`` metres, as wedges (module notes)."""
    threshold = np.radians(check_threshold(threshold_deg))
    unique, counts, pair = _edge_faces(facets.faces)
    keep = counts <= 2
    unique, counts, pair = unique[keep], counts[keep], pair[keep]
    one_sided = counts == 1
    pair[one_sided, 1] = pair[one_sided, 0]
    r0, r1 = facets.vertices[unique[:, 0]], facets.vertices[unique[:, 1]]
    tangents = _unit(r1 - r0)
    n0, n1 = facets.normals[pair[:, 0]], facets.normals[pair[:, 1]]

    def inward(face: np.ndarray) -> np.ndarray:
        d = facets.centroids[face] - r0
        return _unit(d - np.einsum("ij,ij->i", d, tangents)[:, None] * tangents)

    a0, a1 = inward(pair[:, 0]), inward(pair[:, 1])
    # Angle of face 1 around the edge, from face 0 through the outside (the n0 side).
    outside = np.arctan2(np.einsum("ij,ij->i", a1, n0), np.einsum("ij,ij->i", a1, a0))
    outside = np.where(outside < ANGLE_TOL, outside + 2.0 * np.pi, outside)  # a1 = a0: a sheet, 2 pi
    outside[one_sided] = 2.0 * np.pi
    turn = np.arccos(np.clip(np.einsum("ij,ij->i", n0, n1), -1.0, 1.0))
    by_turn = (turn >= threshold) & (outside >= np.pi + threshold - 1e-9)
    radius = _hinge_radius(facets, unique, pair, tangents, turn)
    rounded = ~by_turn & (outside > np.pi + ANGLE_TOL) & (radius <= max_radius)
    sharp = one_sided | by_turn | rounded
    radius = np.where(rounded, radius, 0.0)
    return EdgeSet(
        centres=((r0 + r1) / 2.0)[sharp],
        tangents=tangents[sharp],
        lengths=np.linalg.norm(r1 - r0, axis=1)[sharp],
        inward0=a0[sharp],
        normal0=n0[sharp],
        wedge=np.clip(outside[sharp] / np.pi, 1.0, 2.0),
        faces=pair[sharp],
        one_sided=one_sided[sharp],
        radius=radius[sharp],
    )


def polarisation_basis(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta-hat, phi-hat) [D, 3] of unit directions u: d u / d aspect and d u / d roll, normalised.

    The roll is read back from u (atan2), and taken as 0 at the poles where d u / d roll vanishes:
    the same basis as the SBR part, so that every method answers in one convention.
    """
    rho = np.hypot(u[:, 0], u[:, 1])
    roll = np.where(rho > 1e-12, np.arctan2(u[:, 1], u[:, 0]), 0.0)
    aspect = np.arctan2(rho, u[:, 2])
    theta = np.stack([np.cos(aspect) * np.cos(roll), np.cos(aspect) * np.sin(roll), -np.sin(aspect)], axis=-1)
    phi = np.stack([-np.sin(roll), np.cos(roll), np.zeros_like(roll)], axis=-1)
    return theta, phi


def check_polarization(polarization) -> tuple[tuple[str, ...], bool]:
    """(names, stacked): one of POLARIZATIONS -> ((name,), False); "all" or a sequence of them ->
    (names, True), the output then carrying a trailing polarisation axis in that order."""
    if isinstance(polarization, str):
        name = polarization.upper()
        if name == "ALL":
            return ALL_POLARIZATIONS, True
        if name in POLARIZATIONS:
            return (name,), False
    elif isinstance(polarization, (tuple, list)) and polarization:
        names = tuple(str(p).upper() for p in polarization)
        if all(n in POLARIZATIONS for n in names):
            return names, True
    raise UserInputError(f"polarization: expected one of {', '.join(POLARIZATIONS)} (first letter transmit, "
                         f"second receive), 'all', or a list of them, got {polarization!r}")


# --- wedge coefficients ------------------------------------------------------------------------

def keller(phi: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keller's monostatic wedge coefficients (soft, hard), dimensionless: D = d e^{-j pi/4} / (2 sqrt(2 pi k)).

    d = (2 sin(pi/n) / n) [1 / (cos(pi/n) - 1) -+ 1 / (cos(pi/n) - cos(2 phi / n))], the outside
    wedge angle n pi, phi measured from face 0 (incidence and observation both at phi).
    """
    c = np.cos(np.pi / n)
    g = 2.0 * np.sin(np.pi / n) / n
    incident = 1.0 / (c - 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        reflected = 1.0 / (c - np.cos(2.0 * phi / n))
    return g * (incident - reflected), g * (incident + reflected)


def po_edge(phi: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The same wedge's PO edge terms (soft, hard) in Keller's normalisation: +-tan of the angle
    from each lit face (face 0 is lit for 0 < phi < pi, face 1 for 0 < n pi - phi < pi)."""
    psi = n * np.pi - phi
    with np.errstate(divide="ignore", invalid="ignore"):
        soft = np.where((phi > 0) & (phi < np.pi), np.tan(phi), 0.0)
        soft += np.where((psi > 0) & (psi < np.pi), np.tan(psi), 0.0)
    return soft, -soft


def _fringe_raw(phi: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ks, kh = keller(phi, n)
    ps, ph = po_edge(phi, n)
    return ks - ps, kh - ph


def fringe(phi: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Fringe coefficients (soft, hard) = Keller - PO; finite everywhere on [0, n pi].

    At a face's specular direction (phi = pi/2 or n pi - pi/2) Keller's reflected term and the
    face's PO tan have the same pole, so the difference is smooth but 0/0 there: within
    REFLECTION_GAP of a pole it is interpolated linearly between the two ends (error ~ gap^2).
    """
    phi, n = np.broadcast_arrays(np.asarray(phi, dtype=np.float64), np.asarray(n, dtype=np.float64))
    soft, hard = _fringe_raw(phi, n)
    for pole in (np.full_like(phi, np.pi / 2), n * np.pi - np.pi / 2):
        near = np.abs(phi - pole) < REFLECTION_GAP
        if not near.any():
            continue
        p, m = pole[near], n[near]
        lo, hi = _fringe_raw(p - REFLECTION_GAP, m), _fringe_raw(p + REFLECTION_GAP, m)
        w = (phi[near] - (p - REFLECTION_GAP)) / (2.0 * REFLECTION_GAP)
        soft[near] = (1.0 - w) * lo[0] + w * hi[0]
        hard[near] = (1.0 - w) * lo[1] + w * hi[1]
    return soft, hard


# --- per (edge, direction) geometry -----------------------------------------------------------

def wedge_angles(edges: EdgeSet, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(phi [E, D], outside [E, D]): the angle of u around each edge from face 0 through the
    outside, and whether u lies in the outside wedge (else the edge is behind its own faces)."""
    x = edges.inward0 @ u.T
    y = edges.normal0 @ u.T
    phi = np.arctan2(y, x)
    phi = np.where(phi < -ANGLE_TOL, phi + 2.0 * np.pi, np.maximum(phi, 0.0))
    limit = (edges.wedge * np.pi)[:, None]
    outside = phi <= limit + ANGLE_TOL
    # A one-sided sheet carries PO current on its front only, and so does its edge: the back
    # half-space (phi > pi) sees nothing, as it sees nothing of the sheet.
    outside &= ~edges.one_sided[:, None] | (phi <= np.pi + ANGLE_TOL)
    return np.minimum(phi, limit), outside


def visible(edges: EdgeSet, u: np.ndarray, phi: np.ndarray, outside: np.ndarray, scene, offset: float) -> np.ndarray:
    """[E, D] edges that see the radar: in their outside wedge and with a clear Embree ray toward u.

    The ray starts ``offset`` off the edge midpoint, in the outside wedge at the angle of u kept
    RAY_MARGIN of the outside angle away from both faces, so a grazing ray does not hit its own face.
    """
    if scene is None:
        return outside
    e_idx, d_idx = np.nonzero(outside)
    if len(e_idx) == 0:
        return outside
    span = edges.wedge[e_idx] * np.pi
    angle = np.clip(phi[e_idx, d_idx], RAY_MARGIN * span, (1.0 - RAY_MARGIN) * span)
    lift = np.cos(angle)[:, None] * edges.inward0[e_idx] + np.sin(angle)[:, None] * edges.normal0[e_idx]
    origins = (edges.centres[e_idx] + offset * lift).astype(np.float32)
    clear = scene.run(origins, u.astype(np.float32)[d_idx], query="OCCLUDED") != 0  # embreex: 0 hit, -1 clear
    out = np.zeros_like(outside)
    out[e_idx[clear], d_idx[clear]] = True
    return out


def edge_frame(t: np.ndarray, u: np.ndarray) -> tuple[dict, dict, np.ndarray]:
    """(p.t^, p.w^ for p = "V", "H", each [E, D]; defined [E, D]) for edge tangents t and directions u.

    t^ = (t - (t.u) u) / sin beta, so p.t^ = (p.t) / sin beta for p perpendicular to u;
    w^ = t x u / sin beta, so p.w^ = t.(u x p) / sin beta, with u x theta = phi, u x phi = -theta.
    Looking along an edge (sin beta < 1e-9) both are set to zero.
    """
    theta, phihat = polarisation_basis(u)
    along = t @ u.T  # [E, D] cos beta
    sin_beta = np.sqrt(np.maximum(1.0 - along**2, 0.0))
    ok = sin_beta > 1e-9
    inv = np.divide(1.0, sin_beta, out=np.zeros_like(sin_beta), where=ok)
    t_dot = {"V": (t @ theta.T) * inv, "H": (t @ phihat.T) * inv}
    return t_dot, {"V": t_dot["H"], "H": -t_dot["V"]}, ok


def amplitudes(edges: EdgeSet, u: np.ndarray, phi: np.ndarray, lit: np.ndarray,
               polarizations: tuple[str, ...], frame: tuple | None = None) -> np.ndarray:
    """Real amplitudes [P, E, D] of each (edge, direction) term, zero where the edge is not lit.

    a_pq = L / (2 sqrt(pi)) [f_s (p.t^)(q.t^) - f_h (p.w^)(q.w^)]; t^ and w^ are an orthonormal
    pair across u, so the polarisation factors stay bounded even looking along the edge (where
    t^ is undefined and the term is set to zero). ``frame``: :func:`edge_frame` of the edges and u,
    when the caller already has it.
    """
    soft, hard = fringe(phi, edges.wedge[:, None])
    t_dot, w_dot, defined = edge_frame(edges.tangents, u) if frame is None else frame
    ok = defined & lit
    scale = np.where(ok, edges.lengths[:, None] / (2.0 * _SQRT_PI), 0.0)
    out = np.empty((len(polarizations), edges.n_edges, len(u)))
    for i, name in enumerate(polarizations):
        tx, rx = name[0], name[1]
        out[i] = scale * (soft * t_dot[rx] * t_dot[tx] - hard * w_dot[rx] * w_dot[tx])
    return out


# --- the line-integral sum ---------------------------------------------------------------------

def _sinc(x: np.ndarray) -> np.ndarray:
    """sin(x) / x in place of x's dtype (1 at 0)."""
    out = np.sin(x)
    np.divide(out, x, out=out, where=x != 0)
    out[x == 0] = 1.0
    return out


def _entry_sum(out: np.ndarray, amp: np.ndarray, e_idx, d_idx, phase, half, k, real_dtype) -> None:
    """out[d, n, p] += amp[p, q] exp(j k_n phase_q) sinc(k_n half_q) for the listed pairs q."""
    step = max(1, ENTRY_VALUES // len(k))
    for s in range(0, len(d_idx), step):
        sl = slice(s, s + step)
        values = po.entry_phases(phase[sl], k, real_dtype)  # [Q, N]
        sinc = _sinc(np.outer(half[sl], k).astype(real_dtype))  # |x| < 2 TAU_SINC here: no precision issue
        values.view(real_dtype).reshape(values.shape + (2,))[...] *= sinc[..., None]
        rows = d_idx[sl]
        cols = np.arange(len(rows) + 1)
        for p in range(amp.shape[0]):
            select = scipy.sparse.csc_array((amp[p, e_idx[sl], rows].astype(real_dtype), rows, cols),
                                            shape=(out.shape[0], len(rows)))
            part = select @ values.view(real_dtype)
            out[:, :, p] += part.view(values.dtype)


def edge_sum(edges: EdgeSet, u: np.ndarray, amp: np.ndarray, k: np.ndarray, real_dtype=np.float32) -> np.ndarray:
    """sum_e amp[p, e, d] exp(2jk u.c_e) sinc(k L_e u.t_e) as [D, N, P] for a uniformly spaced block k.

    Pairs with k_min L |u.t| >= TAU_SINC split the sinc into exp(+-jkL u.t) / (2jkL u.t) and go
    through the batched phase sums of the PO kernel; the others (edges near the Keller cone,
    the strong terms) are evaluated per entry with the exact sinc.
    """
    n_pol = amp.shape[0]
    out = np.zeros((len(u), len(k), n_pol), dtype=po.complex_dtype(real_dtype))
    active = (amp != 0).any(axis=0)  # [E, D]
    if not active.any():
        return out
    phase = 2.0 * (u @ edges.centres.T)  # [D, E]
    half = (u @ edges.tangents.T) * edges.lengths  # [D, E] L u.t
    k_lo = float(np.abs(k).min())
    split = active.T & (k_lo * np.abs(half) >= TAU_SINC)
    entry = active.T & ~split
    if split.any():
        both = np.concatenate([phase + half, phase - half], axis=1)  # [D, 2E]
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(split, 1.0 / (2j * half), 0.0)
        for p in range(n_pol):
            coef = (amp[p].T * scale).astype(out.dtype)  # phase_sums views it as real_dtype pairs
            sums = po.phase_sums(both, np.ascontiguousarray(np.concatenate([coef, -coef], axis=1)), k, real_dtype)
            out[:, :, p] += sums / k.astype(real_dtype)
    d_idx, e_idx = np.nonzero(entry)
    if len(d_idx):
        _entry_sum(out, amp, e_idx, d_idx, phase[d_idx, e_idx], half[d_idx, e_idx], k, real_dtype)
    return out


class EdgeDiffraction:
    """The fringe response of one mesh's sharp (and rounded) edges, chunk by chunk of directions."""

    def __init__(self, facets: FacetMesh, threshold_deg: float = SHARP_EDGE_DEG, scene=None,
                 krho: float = ROUNDED_EDGE_KRHO, k_min: float = np.inf, order: int = EDGE_ORDER):
        """``krho`` and ``k_min`` (the lowest wavenumber simulated) bound the rounded edges kept;
        ``order`` 2 adds the double diffraction between facing sheet edges (radar/edge_pairs.py)."""
        from radar2shape.radar.edge_pairs import sheet_pairs

        self.krho = krho
        max_radius = krho / k_min if krho > 0 and k_min > 0 else 0.0
        self.edges = sharp_edges(facets, threshold_deg, max_radius)
        self.pairs = sheet_pairs(self.edges, facets) if check_order(order) >= 2 else None
        self.scene = scene
        self.offset = EDGE_RAY_OFFSET * float(np.linalg.norm(np.ptp(facets.vertices, axis=0)))

    def lit(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(phi, lit) [E, D]: each edge's angle to u and whether it sees the radar (Embree when a scene was given)."""
        phi, outside = wedge_angles(self.edges, u)
        return phi, visible(self.edges, u, phi, outside, self.scene, self.offset)

    def amplitudes(self, u: np.ndarray, polarizations: tuple[str, ...]) -> np.ndarray:
        """[P, E, D] term amplitudes for directions u."""
        phi, lit = self.lit(u)
        return amplitudes(self.edges, u, phi, lit, polarizations)

    def groups(self, k: np.ndarray) -> list[tuple[slice, np.ndarray]]:
        """The edges of one uniformly spaced block ``k`` grouped by the run of k at which they count,
        as (run, edge mask [E]): a rounded edge counts while |k| radius <= krho, a contiguous run of
        a monotone block; sharp edges count at every k. Each edge then goes through one sum."""
        radius = self.edges.radius
        active = np.abs(k)[:, None] * radius[None, :] <= self.krho  # [N, E]
        count = active.sum(axis=0)
        first = active.argmax(axis=0)
        key = first * (len(k) + 1) + count  # >= 1 for an edge that counts somewhere, 0 otherwise
        counted = np.flatnonzero(count > 0)
        leaders = counted[np.unique(key[counted], return_index=True)[1]]
        return [(slice(int(first[e]), int(first[e] + count[e])), key == key[e]) for e in leaders]

    def response(self, u: np.ndarray, k: np.ndarray, polarizations: tuple[str, ...], blocks: list[slice],
                 real_dtype=np.float32) -> np.ndarray:
        """Fringe response [D, N, P] (local-origin phase) of the directions u at wavenumbers k."""
        out = np.zeros((len(u), len(k), len(polarizations)), dtype=po.complex_dtype(real_dtype))
        if self.edges.n_edges == 0:
            return out
        phi, lit = self.lit(u)
        frame = edge_frame(self.edges.tangents, u)  # shared by the single and the pair terms
        amp = amplitudes(self.edges, u, phi, lit, polarizations, frame)
        if self.pairs is not None and self.pairs.n_pairs:
            from radar2shape.radar.edge_pairs import pair_response

            out += pair_response(self.pairs, u, lit, k, frame[1], polarizations, real_dtype)
        for block in blocks:
            for run, members in self.groups(k[block]):
                part = slice(block.start + run.start, block.start + run.stop)
                if members.all():
                    out[:, part] += edge_sum(self.edges, u, amp, k[part], real_dtype)
                else:
                    out[:, part] += edge_sum(self.edges.subset(members), u, amp[:, members], k[part], real_dtype)
        return out
