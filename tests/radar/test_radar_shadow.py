"""Shadowing: a facet hidden behind another carries no current (not only back-face culling)."""

import numpy as np
import trimesh

from radar2shape.radar import simulate
from radar2shape.radar.facets import facet_mesh

FREQ = np.linspace(8e9, 12e9, 8)


def square(z, half, x0=0.0):
    """Two facets, normal +z; facet 0 has its centroid at (x0 + half/3, -half/3)."""
    vertices = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]]) + [x0, 0, 0]
    return trimesh.Trimesh(vertices, [[0, 1, 2], [0, 2, 3]], process=False)


def test_hidden_plate_contributes_nothing():
    front, back = square(0.2, 0.1), square(0.0, 0.1)
    both = trimesh.util.concatenate([front, back])
    aspect, roll = np.array([0.0, 0.05]), np.array([0.0, 1.0])
    shadowed = simulate(both, aspect, roll, FREQ, dtype=np.complex128)
    front_only = simulate(front, aspect, roll, FREQ, dtype=np.complex128)
    back_only = simulate(back, aspect, roll, FREQ, dtype=np.complex128)
    assert np.allclose(shadowed, front_only, rtol=1e-12, atol=0)
    culled = simulate(both, aspect, roll, FREQ, shadowing=False, dtype=np.complex128)
    assert np.allclose(culled, front_only + back_only)  # back-face culling alone keeps it


def test_partly_hidden_plate_keeps_its_visible_facet():
    """A front plate shifted by +x hides only the back facet whose centroid lies under it."""
    front, back = square(0.05, 0.1, x0=0.1), square(0.0, 0.1)
    both = trimesh.util.concatenate([front, back])
    shadowed = simulate(both, [0.0], [0.0], FREQ, dtype=np.complex128)
    visible = trimesh.Trimesh(back.vertices, back.faces[1:], process=False)  # centroid x = -0.033
    expected = simulate(front, [0.0], [0.0], FREQ, dtype=np.complex128) + simulate(visible, [0.0], [0.0], FREQ, dtype=np.complex128)
    assert np.allclose(shadowed, expected, rtol=1e-12, atol=0)


def test_convex_facets_skip_rays():
    """Facets on a supporting plane can never be occluded, so they need no ray."""
    assert facet_mesh(trimesh.creation.icosphere(2)).supported.all()
    torus = facet_mesh(trimesh.creation.torus(0.3, 0.1, major_sections=20, minor_sections=10))
    assert 0.2 < torus.supported.mean() < 0.8
