"""Polarimetric SBR: HH, VV and cross-pol of corner reflectors against their closed forms.

Backscatter alignment (one antenna frame for transmit and receive, V = theta-hat, H = phi-hat):
each PEC reflection maps E to -E + 2 (n.E) n. A 90-degree dihedral's double bounce keeps the
field component along the fold and flips the one across it relative to a plate, so at
boresight S_HH = -S_VV with |S|^2 = 8 pi a^2 b^2 / lambda^2; a trihedral's triple bounce is a
point reflection (like a plate), so S_HH = S_VV. Turned by 45 degrees about the line of sight,
the dihedral's scattering matrix diag(s, -s) becomes [[0, s], [s, 0]]: all the power is cross-pol.
"""

import numpy as np
import pytest

from radar2shape.errors import UserInputError
from radar2shape.radar import sbr
from radar2shape.radar.facets import facet_mesh
from radar2shape.radar.simulator import directions
from test_radar_sbr import K, LAM, TRIHEDRAL_AXIS, db, dihedral, plate, trihedral

BORESIGHT = directions(np.array([np.pi / 2]), np.array([np.pi / 4])).reshape(-1, 3)  # fold along z
AXIS = directions(np.array([TRIHEDRAL_AXIS[0]]), np.array([TRIHEDRAL_AXIS[1]])).reshape(-1, 3)


def responses(mesh, u, **kwargs):
    facets = facet_mesh(mesh)
    return {p: sbr.multibounce(facets, u, np.array([K]), polarization=p, real_dtype=np.float64,
                               workers=1, **kwargs)[0, 0] for p in sbr.POLARIZATIONS}


def rotation(axis, angle):
    """Rodrigues rotation matrix about the unit vector ``axis``."""
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


def test_dihedral_hh_is_minus_vv_at_boresight():
    w = 3 * LAM
    s = responses(dihedral(w, w), BORESIGHT)
    ref = 8 * np.pi * w**4 / LAM**2
    for p in ("VV", "HH"):
        assert abs(db(abs(s[p]) ** 2 / ref)) < 0.1  # measured +0.015 dB
    assert abs(s["HH"] + s["VV"]) < 1e-9 * abs(s["VV"])
    assert max(abs(s["HV"]), abs(s["VH"])) < 1e-9 * abs(s["VV"])


def test_trihedral_hh_equals_vv_on_axis():
    a = 4 * LAM
    s = responses(trihedral(a), AXIS, max_bounces=3, first_bounce=3)
    ref = 4 * np.pi * a**4 / (3 * LAM**2)
    for p in ("VV", "HH"):
        assert abs(db(abs(s[p]) ** 2 / ref)) < 0.2  # measured -0.047 dB
    assert abs(s["HH"] - s["VV"]) < 1e-9 * abs(s["VV"])
    assert max(abs(s["HV"]), abs(s["VH"])) < 1e-9 * abs(s["VV"])


def test_dihedral_turned_45_degrees_is_all_cross_pol():
    w = 5 * LAM
    v, f = dihedral(w, w)
    s = responses((v @ rotation(BORESIGHT[0], np.pi / 4).T, f), BORESIGHT)
    ref = 8 * np.pi * w**4 / LAM**2
    for p in ("HV", "VH"):
        assert abs(db(abs(s[p]) ** 2 / ref)) < 0.3  # measured -0.07 dB
    assert abs(s["HV"] - s["VH"]) < 1e-9 * abs(s["HV"])  # reciprocity
    assert max(abs(s["VV"]), abs(s["HH"])) < 1e-6 * abs(s["HV"])


def test_single_bounce_is_polarisation_free_on_a_plate():
    """One bounce (PO) at broadside: HH = VV = 4 pi A^2 / lambda^2 and no cross-pol."""
    s = responses(plate(3 * LAM, 2 * LAM), np.array([[0.0, 0.0, 1.0]]), max_bounces=1, first_bounce=1,
                  rays_per_wavelength=8)
    ref = 4 * np.pi * (6 * LAM**2) ** 2 / LAM**2
    assert abs(abs(s["VV"]) ** 2 - ref) < 1e-6 * ref
    assert abs(s["HH"] - s["VV"]) < 1e-9 * abs(s["VV"])
    assert max(abs(s["HV"]), abs(s["VH"])) < 1e-9 * abs(s["VV"])


def test_default_is_vv_and_lowercase_is_accepted():
    facets = facet_mesh(dihedral(2 * LAM, 2 * LAM))
    u = directions(np.array([np.pi / 2]), np.array([0.6])).reshape(-1, 3)
    default = sbr.multibounce(facets, u, np.array([K, 1.1 * K]), workers=1)
    np.testing.assert_array_equal(sbr.multibounce(facets, u, np.array([K, 1.1 * K]), polarization="vv", workers=1),
                                  default)


@pytest.mark.parametrize("value", ["XY", "V", "", None, 3, [], ["VV", "XX"]])
def test_bad_polarization(value):
    with pytest.raises(UserInputError, match="polarization"):
        sbr.multibounce(facet_mesh(plate(LAM, LAM)), np.array([[0.0, 0.0, 1.0]]), np.array([K]),
                        polarization=value)


def test_one_trace_gives_every_channel():
    """A list of names: [D, N, P] from one ray trace, equal to tracing each channel alone."""
    v, f = dihedral(3 * LAM, 2 * LAM)
    facets = facet_mesh((v @ rotation(np.array([0.6, 0.0, 0.8]), 0.5).T, f))
    u = directions(np.radians([70.0, 95.0]), np.radians([30.0, 50.0])).reshape(-1, 3)
    k = np.array([0.9, 1.0, 1.1]) * K
    names = ["VV", "VH", "HV", "HH"]
    stacked = sbr.multibounce(facets, u, k, polarization=names, real_dtype=np.float64, workers=1)
    assert stacked.shape == (4, 3, 4) and np.abs(stacked[..., 1]).max() > 1e-3 * np.abs(stacked).max()
    for i, name in enumerate(names):
        alone = sbr.multibounce(facets, u, k, polarization=name, real_dtype=np.float64, workers=1)
        np.testing.assert_allclose(stacked[..., i], alone, rtol=1e-12, atol=1e-12 * np.abs(stacked).max())
