"""Double diffraction between facing sheet edges (radar/edge_pairs.py).

The strip reference is written from the 2-D uniform GTD picture only (Kouyoumjian-Pathak's
half-plane coefficient with its transition function F, here through the complex erfc rather than
the Fresnel integrals the module uses): the two round trips between the edges, each with the
grazing wave counted once at half field, times L / (2 sqrt(pi)) as for single diffraction.
"""

import numpy as np
import pytest
import trimesh
from scipy.special import erfc

from radar2shape.errors import UserInputError
from radar2shape.radar import edges
from radar2shape.radar.edge_pairs import sheet_pairs
from radar2shape.radar.facets import facet_mesh
from radar2shape.radar.po import wavenumbers
from radar2shape.radar.simulator import simulate
from radar2shape.radar.validation import plate

F_HZ = 10e9
K = float(wavenumbers(np.array([F_HZ]))[0])
LAM = 2 * np.pi / K


def transition(x):
    """UTD transition function F(x) = 2j sqrt(x) e^{jx} int_{sqrt x}^inf e^{-j t^2} dt, via erfc."""
    root = np.sqrt(x)
    tail = np.sqrt(np.pi) / 2 * np.exp(-1j * np.pi / 4) * erfc(root * np.exp(1j * np.pi / 4))
    return 2j * root * np.exp(1j * x) * tail


def half_plane_hard(phi, phi_in, dist):
    """Bistatic hard half-plane coefficient, in units of e^{-j pi/4} / (2 sqrt(2 pi k)) (the d of test_edges),
    lit by a cylindrical wave from ``dist`` away (UTD distance parameter)."""
    total = 0
    for beta in (phi - phi_in, phi + phi_in):
        total = total + transition(K * dist * 2 * np.cos(beta / 2) ** 2) / np.cos(beta / 2)
    return -total


def strip_double(width, length, aspect):
    """Hard double-diffraction return of a strip (edges along y at x = +-width/2) seen from (sin a, 0, cos a)."""
    near, far = np.pi / 2 + aspect, np.pi / 2 - aspect  # each edge's angle to u from its face
    # 2-D: u2 / u_i = 2 round trips x 1/2 (grazing) x D1 D2 e^{-jkd} / sqrt(d), D = d e^{-j pi/4} / (2 sqrt(2 pi k))
    d1, d2 = half_plane_hard(0.0, far, width), half_plane_hard(near, 0.0, width)
    u2 = d1 * d2 * np.exp(-1j * np.pi / 2) / (8 * np.pi * K) * np.exp(-1j * K * width) / np.sqrt(width)
    d_eff = u2 * 2 * np.sqrt(2 * np.pi * K) * np.exp(1j * np.pi / 4)
    return -length / (2 * np.sqrt(np.pi)) * d_eff  # hard terms carry the minus of test_edges


@pytest.mark.parametrize("aspect_deg", [10.0, 40.0, 70.0, 85.0])
def test_plate_double_diffraction_matches_strip_utd(aspect_deg):
    """Plate 3 x 24 lambda, u across the long edges: (order 2) - (order 1) is the strip's hard
    double-diffraction term, in VV (E across the edges); HH (soft) gets only the short edges'
    far off-cone pair term."""
    w, length = 3 * LAM, 24 * LAM
    mesh = plate(length, w, normal_axis=2, long_axis=0)  # x extent w, y extent length
    a = np.radians(aspect_deg)
    one, two = (simulate(mesh, [a], [0.0], [F_HZ], method="po+ec", polarization="all", dtype=np.complex128,
                         edge_order=order)[0, 0, 0] for order in (1, 2))
    added = two - one
    expected = strip_double(w, length, a)
    vv, vh, hv, hh = added
    assert abs(vv - expected) < 0.03 * abs(expected)
    assert abs(hh) < 0.05 * abs(expected) and abs(hv) < 1e-12 and abs(vh) < 1e-12


def test_plate_is_dark_edge_on_in_the_hard_polarisation():
    """A zero-thickness plate seen edge-on with E normal to it does not scatter (the incident field
    meets the boundary condition). Single diffraction leaves the far edge's return; the facing-edge
    wave cancels it, and the return falls smoothly toward grazing."""
    mesh = plate(12 * LAM, 3 * LAM, normal_axis=2, long_axis=1)
    aspects = np.radians([80.0, 85.0, 88.0, 90.0])
    one, two = (np.abs(simulate(mesh, aspects, [0.0], [F_HZ], method="po+ec", polarization="VV",
                                dtype=np.complex128, edge_order=order)[:, 0, 0]) for order in (1, 2))
    assert 20 * np.log10(two[-1] / one[-1]) < -40
    assert np.all(np.diff(two[1:]) < 0)  # toward grazing the hard return keeps falling


def test_pairs_need_facing_edges_with_sheet_between():
    """A plate has its two pairs of opposite edges; a plate split in two with a gap between the halves
    pairs each half's own edges only; a finely meshed plate pairs overlapping pieces whose overlaps
    add up to the side; a closed box has no sheet edges at all."""
    def pairs_of(mesh):
        facets = facet_mesh(mesh)
        return sheet_pairs(edges.sharp_edges(facets), facets)

    one = pairs_of(plate(0.3, 0.2))
    assert one.n_pairs == 2 and sorted(np.round(one.separation, 9)) == [0.2, 0.3]
    assert sorted(np.round(one.overlap, 9)) == [0.2, 0.3]
    halves = trimesh.util.concatenate([plate(0.1, 0.2).apply_translation([-0.15, 0, 0]),  # x in [-0.25, -0.05]
                                       plate(0.1, 0.2).apply_translation([0.15, 0, 0])])  # and [0.05, 0.25]
    split = pairs_of(halves)
    assert split.n_pairs == 4 and sorted(np.round(split.separation, 9)) == [0.1, 0.1, 0.2, 0.2]  # none across the gap
    touching = trimesh.util.concatenate([plate(0.1, 0.2).apply_translation([-0.1, 0, 0]),
                                         plate(0.1, 0.2).apply_translation([0.1, 0, 0])])
    assert np.isclose(pairs_of(touching).separation, 0.4).sum() == 1  # two sheets that meet form one
    fine = trimesh.Trimesh(*trimesh.remesh.subdivide(*trimesh.remesh.subdivide(plate(0.3, 0.2).vertices,
                                                                                plate(0.3, 0.2).faces)), process=False)
    fine_pairs = pairs_of(fine)
    for gap, side in ((0.2, 0.3), (0.3, 0.2)):
        sel = np.isclose(fine_pairs.separation, gap)
        assert np.isclose(fine_pairs.overlap[sel].sum(), side)
    assert pairs_of(trimesh.creation.box((0.3, 0.2, 0.1))).n_pairs == 0


def test_edge_order_checks():
    mesh = plate(0.3, 0.2)
    for bad in (0, 3, 1.5, "2", True):
        with pytest.raises(UserInputError, match="edge_order"):
            simulate(mesh, [0.0], [0.0], [1e9], method="po+ec", edge_order=bad)


def test_closed_solids_and_rotations_are_unchanged_by_the_pairs():
    """No sheet edges on a box: order 2 equals order 1 bit for bit; on a tilted plate the pair terms
    keep S_HV = S_VH (reciprocity)."""
    box = trimesh.creation.box((0.3, 0.2, 0.1))
    a, r = np.radians([20.0, 50.0]), np.radians([10.0, 70.0])
    one, two = (simulate(box, a, r, [F_HZ], method="po+ec", polarization="all", edge_order=o) for o in (1, 2))
    assert np.array_equal(one, two)
    tilted = plate(0.3, 0.2).apply_transform(trimesh.transformations.rotation_matrix(0.4, [1, 1, 0]))
    s = simulate(tilted, a, r, np.array([8e9, 12e9]), method="po+ec", polarization="all", dtype=np.complex128)
    assert np.allclose(s[..., 1], s[..., 2], rtol=1e-9, atol=1e-12)


def test_transition_tail_matches_erfc_on_both_branches():
    """e^{jx} T(sqrt x): Fresnel integrals below the series threshold, asymptotic series above it;
    both against the complex erfc form, across the switch."""
    from radar2shape.radar.edge_pairs import SERIES_FROM, _tail

    x = np.concatenate([np.linspace(0.0, 3 * SERIES_FROM, 3001), np.geomspace(3 * SERIES_FROM, 1e5, 200)])
    reference = np.exp(1j * x) * np.sqrt(np.pi) / 2 * np.exp(-1j * np.pi / 4) * erfc(np.sqrt(x) * np.exp(1j * np.pi / 4))
    assert np.max(np.abs(_tail(x) - reference) / np.abs(reference)) < 1e-7


def test_pair_candidates_stay_within_direction_groups():
    """Candidates pair only edges of one tangent direction: a 16-gon sheet's 16 boundary edges make
    8 parallel pairs (opposite sides), not 120; its facing pairs are those 8."""
    from radar2shape.radar.edge_pairs import _parallel_candidates

    ring = trimesh.creation.cylinder(radius=0.2, height=0.01, sections=16)
    disk = trimesh.Trimesh(ring.vertices, ring.faces[np.abs(ring.face_normals[:, 2] - 1) < 1e-9], process=False)
    facets = facet_mesh(disk)
    sharp = edges.sharp_edges(facets)
    i, j = _parallel_candidates(sharp)
    assert sharp.n_edges == 16 and len(i) == 8
    pairs = sheet_pairs(sharp, facets)
    assert pairs.n_pairs == 8 and np.allclose(pairs.separation, 2 * 0.2 * np.cos(np.pi / 16))
