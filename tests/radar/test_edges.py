"""Equivalent edge currents (radar/edges.py): PO + fringe against first-order GTD closed forms.

The references below are written from the 2-D picture only: an infinitely long wedge edge lit
and observed perpendicular to itself scatters u_d = u_i D e^{-jk rho} / sqrt(rho), with Keller's
wedge coefficient D; a straight edge of length L turns that 2-D field into a 3-D return of
S = L d / (2 sqrt(pi)) (d = D 2 sqrt(2 pi k) e^{j pi/4}, so |S|^2 = 2 k L^2 |D|^2, the usual
2-D to 3-D scaling sigma_3D = 2 L^2 sigma_2D / lambda). Summing the edges of a strip or a box
cross-section with their round-trip phases gives the closed-form GTD return; no PO enters.
"""

import numpy as np
import pytest
import trimesh

from radar2shape.errors import UserInputError
from radar2shape.geometry.almond import nasa_almond
from radar2shape.radar import edges
from radar2shape.radar.facets import facet_mesh
from radar2shape.radar.po import wavenumbers
from radar2shape.radar.simulator import simulate
from radar2shape.radar.validation import plate

F_HZ = 10e9
K = float(wavenumbers(np.array([F_HZ]))[0])
LAM = 2 * np.pi / K


def keller_d(phi, n):
    """Keller's monostatic wedge coefficient (soft, hard), scaled by 2 sqrt(2 pi k) e^{j pi/4}."""
    g = 2 * np.sin(np.pi / n) / n
    a, b = 1 / (np.cos(np.pi / n) - 1), 1 / (np.cos(np.pi / n) - np.cos(2 * phi / n))
    return g * (a - b), g * (a + b)


def gtd_principal_plane(corners, faces_out, aspect, length):
    """First-order GTD return (soft, hard) of a long prism along y seen from u = (sin a, 0, cos a).

    ``corners`` [C, 2] (x, z) of the cross-section's edges; ``faces_out`` [C, 2, 2] the unit
    directions (x, z) away from each edge along its two faces, such that sweeping
    counter-clockwise from the second to the first passes through the outside.
    """
    u = np.array([np.sin(aspect), np.cos(aspect)])
    soft = hard = 0.0
    for c, (f0, f1) in zip(corners, faces_out):
        ang = lambda v: np.arctan2(v[1], v[0])
        # outside wedge angle from face 1 round to face 0 (through the outside)
        start, stop = ang(f1), ang(f0)
        outside = (stop - start) % (2 * np.pi) or 2 * np.pi
        phi = (ang(u) - start) % (2 * np.pi)
        if phi > outside:
            continue  # the radar is behind this edge's faces
        ds, dh = keller_d(phi, outside / np.pi)
        phase = np.exp(2j * K * (u @ c))
        soft, hard = soft + ds * phase, hard + dh * phase
    scale = length / (2 * np.sqrt(np.pi))
    return scale * soft, -scale * hard  # E along the edge (soft) and H along it (hard)


def db(z):
    return 20 * np.log10(np.abs(z))


def test_half_plane_fringe_closed_form():
    """For a half-plane (n = 2) Keller minus PO is -1 +- tan(pi/4 - phi/2) on the lit side, finite
    at the face's specular direction phi = pi/2 where both have a pole (hand-derived)."""
    phi = np.concatenate([np.linspace(0.0, np.pi, 181), np.pi / 2 + np.array([-1e-4, 0.0, 1e-4, 5e-4])])
    soft, hard = edges.fringe(phi, np.full_like(phi, 2.0))
    t = np.tan(np.pi / 4 - phi / 2)
    assert np.allclose(soft, -1 + t, atol=1e-6) and np.allclose(hard, -1 - t, atol=1e-6)
    # soft vanishes at grazing along the face; hard vanishes edge-on from the far side
    assert abs(soft[0]) < 1e-12 and abs(hard[180]) < 1e-12


def test_wedge_fringe_is_finite_at_both_specular_directions():
    n = np.full(2001, 1.5)
    phi = np.linspace(0.0, 1.5 * np.pi, 2001)
    soft, hard = edges.fringe(phi, n)
    assert np.isfinite(soft).all() and np.isfinite(hard).all()
    # smooth: no jump larger than the local slope allows between neighbours
    assert np.abs(np.diff(soft)).max() < 0.05 and np.abs(np.diff(hard)).max() < 0.05


@pytest.mark.parametrize("aspect_deg", [20.0, 50.0, 75.0, 85.0, 88.0, 90.0])
def test_plate_principal_plane_matches_strip_gtd(aspect_deg):
    """Single diffraction (edge_order 1). Plate 3 lambda (x, in the plane of incidence) by 12 lambda (y), u in the x-z plane:
    PO + fringe = Keller's half-plane coefficients of the two y-edges, both polarisations,
    up to grazing (90 deg: edge-on, where PO is zero). The x-edges, off their Keller cone, add
    terms of relative size ~1 / (k L_y): the tolerance."""
    w, length = 3 * LAM, 12 * LAM
    mesh = plate(length, w, normal_axis=2, long_axis=0)  # x extent w, y extent length
    a = np.radians(aspect_deg)
    got = simulate(mesh, [a], [0.0], [F_HZ], method="po+ec", polarization="all", dtype=np.complex128,
                   edge_order=1)[0, 0, 0]
    corners = np.array([[w / 2, 0.0], [-w / 2, 0.0]])
    faces_out = np.array([[[-1, 0], [-1, 0]], [[1, 0], [1, 0]]], dtype=float)
    soft, hard = gtd_principal_plane(corners, faces_out, a, length)
    vv, vh, hv, hh = got  # E along y (the edges) is phi-hat at roll 0: HH is soft, VV hard
    assert abs(db(hh) - db(soft)) < 0.15 and abs(db(vv) - db(hard)) < 0.15
    assert abs(np.angle(hh / soft)) < 0.03 and abs(np.angle(vv / hard)) < 0.03
    assert abs(hv) < 1e-9 * abs(hh) and abs(vh) < 1e-9 * abs(hh)  # principal plane: no cross-pol


@pytest.mark.parametrize("aspect_deg", [25.0, 40.0, 60.0, 80.0])
def test_box_edges_match_right_angle_wedge_gtd(aspect_deg):
    """Box 2 x 1.5 x 30 lambda (x, z, y): its four long edges are right-angle wedges (n = 3/2).
    Away from the faces' specular directions PO + fringe = Keller's n = 3/2 coefficient summed
    over the lit edges with their phases."""
    ax, az, length = 2 * LAM, 1.5 * LAM, 30 * LAM
    mesh = trimesh.creation.box((ax, length, az))
    a = np.radians(aspect_deg)
    got = simulate(mesh, [a], [0.0], [F_HZ], method="po+ec", polarization=("VV", "HH"),
                   dtype=np.complex128)[0, 0, 0]
    # corners counter-clockwise in (x, z); face 0 leaves toward the next corner, face 1 toward the previous
    corners = np.array([[ax / 2, az / 2], [-ax / 2, az / 2], [-ax / 2, -az / 2], [ax / 2, -az / 2]])
    nxt, prv = np.roll(corners, -1, axis=0) - corners, np.roll(corners, 1, axis=0) - corners
    faces_out = np.stack([nxt / np.linalg.norm(nxt, axis=1)[:, None], prv / np.linalg.norm(prv, axis=1)[:, None]], 1)
    soft, hard = gtd_principal_plane(corners, faces_out, a, length)
    vv, hh = got  # the 8 short edges, off their Keller cones, add ~1 / (k L) relative: the tolerance
    assert abs(db(hh) - db(soft)) < 0.12 and abs(db(vv) - db(hard)) < 0.12
    assert abs(np.angle(hh / soft)) < 0.03 and abs(np.angle(vv / hard)) < 0.03


def test_smooth_bodies_get_no_edges():
    """A level-3 icosphere (normals turn 5.8 deg), a level-2 one (11.4 deg) and the 9k-face almond
    (at most 20.5 deg) have no edge above the 30 deg threshold: PO + EC is PO, to the bit (the
    spheres' radius, k rho >= 17, is far from rounded-edge size)."""
    for mesh in (trimesh.creation.icosphere(3, radius=0.1), trimesh.creation.icosphere(2, radius=0.1),
                 nasa_almond(n_around=64, n_back=24, n_front=48)):
        assert edges.sharp_edges(facet_mesh(mesh)).n_edges == 0
    mesh = trimesh.creation.icosphere(3, radius=0.1)
    a, p = np.radians([0, 50, 120]), np.radians([0, 33])
    po = simulate(mesh, a, p, [8e9, 12e9], polarization="all")
    ec = simulate(mesh, a, p, [8e9, 12e9], method="po+ec", polarization="all")
    assert np.array_equal(po, ec)
    almond = nasa_almond(n_around=64, n_back=24, n_front=48)
    po = simulate(almond, [np.pi / 2], p, [7e9], polarization="all")
    assert np.array_equal(po, simulate(almond, [np.pi / 2], p, [7e9], method="po+ec", polarization="all", edge_krho=0))


def test_rounded_edge_radius_of_a_prism():
    """A 24-sided prism inscribed in a cylinder of radius a: every side edge turns by 15 deg, and
    the circle through it and its two opposite vertices is the cylinder's: radius a exactly."""
    a, sides = 0.05, 24
    prism = facet_mesh(trimesh.creation.cylinder(radius=a, height=0.3, sections=sides))
    expected = a
    assert edges.sharp_edges(prism).n_edges == 2 * sides  # the two rims only (90 deg)
    rounded = edges.sharp_edges(prism, max_radius=1.01 * a)
    side = rounded.radius > 0
    assert side.sum() == sides and np.allclose(rounded.radius[side], expected, rtol=1e-9)
    assert np.allclose(np.abs(rounded.tangents[side, 2]), 1.0)  # the side edges run along the axis
    assert edges.sharp_edges(prism, max_radius=0.99 * expected).n_edges == 2 * sides


def test_rounded_edges_count_per_frequency():
    """A band simulated at once equals each frequency simulated alone: a rounded edge counts at
    exactly the wavenumbers where k rho <= edge_krho, whatever else is in the band."""
    almond = nasa_almond(n_around=32, n_back=12, n_front=24)
    freq = np.linspace(2e9, 12e9, 11)  # the rim's k rho crosses 1 inside the band
    ed = edges.EdgeDiffraction(facet_mesh(almond), krho=1.0, k_min=wavenumbers(freq).min())
    assert len(ed.groups(wavenumbers(freq))) > 2
    phi = np.radians([0, 30, 90, 150])
    band = simulate(almond, [np.pi / 2], phi, freq, method="po+ec", polarization="all", dtype=np.complex128)
    for i, f in enumerate(freq):
        alone = simulate(almond, [np.pi / 2], phi, [f], method="po+ec", polarization="all", dtype=np.complex128)
        assert np.abs(band[:, :, i] - alone[:, :, 0]).max() < 1e-9 * np.abs(band).max()
    po = simulate(almond, [np.pi / 2], phi, freq, polarization="all", dtype=np.complex128)
    assert np.abs(band - po).max() > 1e-2 * np.abs(po).max()  # the rim does diffract


def test_sharp_edge_extraction():
    box = edges.sharp_edges(facet_mesh(trimesh.creation.box((1.0, 2.0, 3.0))))
    assert box.n_edges == 12  # the six face diagonals are flat
    assert np.allclose(box.wedge, 1.5) and np.isclose(box.lengths.sum(), 4 * (1 + 2 + 3))
    sheet = edges.sharp_edges(facet_mesh(plate(1.0, 2.0)))  # double-sided: boundary edges of two faces
    assert sheet.n_edges == 4 and np.allclose(sheet.wedge, 2.0) and not sheet.one_sided.any()
    one = edges.sharp_edges(facet_mesh((np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), np.array([[0, 1, 2]]))))
    assert one.n_edges == 3 and one.one_sided.all()
    for bad in (0.0, -5.0, 200.0, "x"):
        with pytest.raises(UserInputError, match="edge_threshold_deg"):
            edges.sharp_edges(facet_mesh(trimesh.creation.box()), bad)


def test_edge_sum_matches_direct_evaluation():
    """The vectorised sum (split sinc through phase sums + exact per-entry sinc) against a direct
    loop, over a wide band and directions both on and off the edges' Keller cones."""
    rng = np.random.default_rng(0)
    mesh = trimesh.creation.box((0.3, 0.2, 0.1))
    ed = edges.sharp_edges(facet_mesh(mesh))
    u = rng.normal(size=(7, 3))
    u[0] = [0, 0.6, 0.8]  # perpendicular to the x edges
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    k = wavenumbers(np.linspace(5e9, 10e9, 9))
    amp = rng.normal(size=(2, ed.n_edges, len(u)))
    got = edges.edge_sum(ed, u, amp, k, np.float64)
    ref = np.zeros_like(got)
    for d in range(len(u)):
        for e in range(ed.n_edges):
            x = k * ed.lengths[e] * (u[d] @ ed.tangents[e])
            term = np.exp(2j * k * (u[d] @ ed.centres[e])) * np.sinc(x / np.pi)
            ref[d, :, 0] += amp[0, e, d] * term
            ref[d, :, 1] += amp[1, e, d] * term
    assert np.abs(got - ref).max() < 1e-9 * np.abs(ref).max()


def test_hidden_plate_edges_add_nothing():
    """A small plate behind a larger one (seen face-on from +z): Embree rays hide its edges."""
    front = plate(0.4, 0.4)
    back = plate(0.1, 0.1)
    back.apply_translation([0, 0, -0.2])
    both = trimesh.util.concatenate([front, back])
    a = np.radians([0.0, 10.0, 20.0])
    alone = simulate(front, a, [0.3], [10e9], method="po+ec", polarization="all", dtype=np.complex128)
    # the back plate is lit only from behind the front one: same response as the front plate alone
    hidden = simulate(both, a, [0.3], [10e9], method="po+ec", polarization="all", dtype=np.complex128)
    assert np.allclose(hidden, alone, rtol=0, atol=1e-9 * np.abs(alone).max())
