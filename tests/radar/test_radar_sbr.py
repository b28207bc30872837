"""SBR hybrid (PO first bounce + ray sum): normalisation, closed forms, convex bodies, bad input."""

import numpy as np
import pytest
import trimesh

from radar2shape.errors import UserInputError
from radar2shape.radar import po, sbr, simulate
from radar2shape.radar.facets import facet_mesh
from radar2shape.radar.simulator import directions

C = 299_792_458.0
FREQ = 10e9
LAM = C / FREQ
K = 2 * np.pi / LAM


def db(x):
    return 10 * np.log10(x)


def plate(w, h):
    v = np.array([[-w / 2, -h / 2, 0], [w / 2, -h / 2, 0], [w / 2, h / 2, 0], [-w / 2, h / 2, 0]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def dihedral(w, h):
    """Plate 1 in y = 0 (x in [0, w]), plate 2 in x = 0 (y in [0, w]), fold along z, height h."""
    v = np.array([[0, 0, -h / 2], [w, 0, -h / 2], [w, 0, h / 2], [0, 0, h / 2], [0, w, -h / 2], [0, w, h / 2]])
    return v, np.array([[0, 1, 2], [0, 2, 3], [0, 3, 5], [0, 5, 4]])


def trihedral(a):
    v = np.array([[0, 0, 0], [a, 0, 0], [0, a, 0], [0, 0, a]])
    return v, np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1]])


TRIHEDRAL_AXIS = (np.arccos(1 / np.sqrt(3)), np.pi / 4)


def test_single_bounce_ray_sum_is_po_on_a_plate():
    """The exit formula's normalisation: one bounce of SBR = PO broadside (|S|^2 and phase)."""
    mesh = plate(3 * LAM, 2 * LAM)
    facets = facet_mesh(mesh)
    u = np.array([[0.0, 0.0, 1.0]])
    ray = sbr.multibounce(facets, u, np.array([K]), max_bounces=1, rays_per_wavelength=8,
                          real_dtype=np.float64, first_bounce=1)[0, 0]
    ref = simulate(mesh, [0.0], [0.0], [FREQ], dtype=np.complex128)[0, 0, 0]
    assert abs(ray - ref) < 1e-6 * abs(ref)
    assert abs(abs(ref) ** 2 - 4 * np.pi * (6 * LAM**2) ** 2 / LAM**2) < 1e-6 * abs(ref) ** 2


@pytest.mark.parametrize("phi_deg", [45.0, 30.0, 20.0])
def test_dihedral_closed_form(phi_deg):
    w = h = 3 * LAM
    phi = np.radians(phi_deg)
    s = simulate(dihedral(w, h), [np.pi / 2], [phi], [FREQ], method="sbr", rays_per_wavelength=8)[0, 0, 0]
    ref = 16 * np.pi * w**2 * h**2 / LAM**2 * min(np.sin(phi), np.cos(phi)) ** 2
    assert abs(db(abs(s) ** 2 / ref)) < 0.5


def test_dihedral_needs_the_second_bounce():
    w = h = 3 * LAM
    po_only = simulate(dihedral(w, h), [np.pi / 2], [np.pi / 4], [FREQ])[0, 0, 0]
    assert db(abs(po_only) ** 2 + 1e-30) - db(8 * np.pi * w**2 * h**2 / LAM**2) < -10


def test_trihedral_triple_bounce_term():
    """The ray sum of the third bounce alone against 4 pi a^4 / (3 lambda^2), a = 4 lambda."""
    a = 4 * LAM
    facets = facet_mesh(trihedral(a))
    u = directions(np.array([TRIHEDRAL_AXIS[0]]), np.array([TRIHEDRAL_AXIS[1]])).reshape(-1, 3)
    s = sbr.multibounce(facets, u, np.array([K]), max_bounces=3, rays_per_wavelength=8, first_bounce=3)[0, 0]
    assert abs(db(abs(s) ** 2 / (4 * np.pi * a**4 / (3 * LAM**2)))) < 0.2


def test_trihedral_closed_form_over_a_band():
    """Full hybrid (its 1- and 2-bounce PO terms are ~-31 dB at a = 16 lambda) on axis, 5 frequencies."""
    a = 16 * LAM
    freq = np.linspace(9.5e9, 10.5e9, 5)
    s = simulate(trihedral(a), [TRIHEDRAL_AXIS[0]], [TRIHEDRAL_AXIS[1]], freq, method="sbr",
                 rays_per_wavelength=8, max_bounces=5)[0, 0]
    ref = 4 * np.pi * a**4 / (3 * (C / freq) ** 2)
    assert np.abs(db(np.abs(s) ** 2 / ref)).max() < 0.5


@pytest.mark.parametrize("mesh", [trimesh.creation.box(extents=(3 * LAM, 2 * LAM, 4 * LAM)),
                                  trimesh.creation.icosphere(3, radius=2 * LAM)])
def test_convex_body_sbr_equals_po(mesh):
    aspect, roll, freq = np.radians([37.0, 71.0]), np.radians([23.0, 111.0]), np.linspace(8e9, 12e9, 4)
    s = simulate(mesh, aspect, roll, freq, method="sbr", rays_per_wavelength=8)
    p = simulate(mesh, aspect, roll, freq)
    assert np.abs(20 * np.log10(np.abs(s) / np.abs(p))).max() < 0.5


def test_one_bounce_is_po():
    v, f = dihedral(2 * LAM, 2 * LAM)
    s = simulate((v, f), [np.pi / 2], [0.7], [FREQ], method="sbr", max_bounces=1)
    np.testing.assert_array_equal(s, simulate((v, f), [np.pi / 2], [0.7], [FREQ]))


def test_non_uniform_frequencies_match_uniform_path():
    v, f = dihedral(2 * LAM, 2 * LAM)
    freq = np.array([8e9, 9e9, 10e9])
    uniform = simulate((v, f), [np.pi / 2], [0.5], freq, method="sbr", dtype=np.complex128)
    uneven = simulate((v, f), [np.pi / 2], [0.5], np.append(freq, 10.5e9), method="sbr", dtype=np.complex128)
    # the ray spacing follows the highest frequency, so compare magnitudes loosely
    np.testing.assert_allclose(np.abs(uneven[..., :3]), np.abs(uniform), rtol=0.1)


@pytest.mark.parametrize("kwargs, match", [
    ({"max_bounces": 0}, "max_bounces"), ({"max_bounces": -2}, "max_bounces"), ({"max_bounces": 2.5}, "max_bounces"),
    ({"rays_per_wavelength": 0}, "rays_per_wavelength"), ({"rays_per_wavelength": -1.0}, "rays_per_wavelength"),
    ({"rays_per_wavelength": float("nan")}, "rays_per_wavelength"),
    ({"rays_per_wavelength": "x"}, "rays_per_wavelength"),
])
def test_bad_options(kwargs, match):
    with pytest.raises(UserInputError, match=match):
        simulate(plate(LAM, LAM), [0.0], [0.0], [FREQ], method="sbr", **kwargs)


def test_launch_grid_covers_the_disk():
    offsets = sbr.launch_offsets(1.0, 0.1)
    assert np.hypot(*offsets.T).max() <= 1.1 + 1e-12
    assert np.pi * 1.0**2 <= len(offsets) * 0.01 <= np.pi * 1.1**2
    assert np.allclose(po.wavenumbers([C]), 2 * np.pi)


def run_cli(*argv):
    import argparse

    from radar2shape.commands import simulate as command

    parser = argparse.ArgumentParser()
    command.configure_parser(parser)
    return command.main(parser.parse_args([str(a) for a in argv]))


def test_cli_sbr_dihedral(tmp_path):
    from radar2shape.radar import load_response

    path, out = tmp_path / "dihedral.obj", tmp_path / "r.npz"
    trimesh.Trimesh(*dihedral(0.1, 0.1), process=False).export(path)
    assert run_cli(path, "--out", out, "--keep-size", "--aspect-deg", "90:90:1", "--roll-deg", "45:45:1",
                   "--freq-ghz", "10:10:1", "--method", "sbr", "--bounces", "2", "--rays-per-wavelength", "6") == 0
    sigma = abs(load_response(out).response[0, 0, 0]) ** 2
    assert abs(db(sigma / (8 * np.pi * 0.1**4 / LAM**2))) < 0.5


@pytest.mark.parametrize("extra, match", [(["--bounces", "0"], "max_bounces"),
                                          (["--rays-per-wavelength", "-2"], "rays_per_wavelength")])
def test_cli_bad_sbr_options(tmp_path, extra, match):
    path = tmp_path / "plate.obj"
    trimesh.Trimesh(*plate(0.1, 0.1), process=False).export(path)
    with pytest.raises(UserInputError, match=match):
        run_cli(path, "--out", tmp_path / "r.npz", "--freq-ghz", "10:10:1", "--method", "sbr", *extra)


@pytest.mark.parametrize("phi_deg", [45.0, 30.0])
def test_dihedral_across_the_fold_polarisation(phi_deg):
    """Fold along y, radar in the xz plane: theta-hat lies across the fold (above: along it)."""
    v, f = dihedral(3 * LAM, 3 * LAM)
    v = v @ np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # (x, y, z) -> (x, z, -y): fold z -> y
    phi = np.radians(phi_deg)
    s = simulate((v, f), [np.pi / 2 + phi], [0.0], [FREQ], method="sbr")[0, 0, 0]
    ref = 16 * np.pi * (3 * LAM) ** 4 / LAM**2 * min(np.sin(phi), np.cos(phi)) ** 2
    assert abs(db(abs(s) ** 2 / ref)) < 0.5
