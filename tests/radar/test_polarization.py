"""Polarimetric output: basis, default unchanged, reciprocity, rotation covariance, files, CLI, configs."""

import argparse

import numpy as np
import pytest
import trimesh

from radar2shape.commands import simulate as command
from radar2shape.errors import UserInputError
from radar2shape.radar import edges, load_response, save_response
from radar2shape.radar.simulator import directions, simulate
from radar2shape.radar.validation import plate

F = [8e9, 10e9, 12e9]


def tilted_plate():
    """A 0.2 x 0.3 m double-sided plate whose normal leans 40 deg from z toward x."""
    mesh = plate(0.2, 0.3)
    return mesh.apply_transform(trimesh.transformations.rotation_matrix(np.radians(40), [0, 1, 0]))


def test_basis_is_the_normalised_derivative():
    a, p, h = 0.7, 2.1, 1e-6
    u = directions(np.array([a]), np.array([p]))[0, 0]
    theta, phi = edges.polarisation_basis(u[None])
    da = (directions(np.array([a + h]), np.array([p])) - directions(np.array([a - h]), np.array([p])))[0, 0] / (2 * h)
    dp = (directions(np.array([a]), np.array([p + h])) - directions(np.array([a]), np.array([p - h])))[0, 0] / (2 * h)
    assert np.allclose(theta[0], da, atol=1e-8) and np.allclose(phi[0], dp / np.linalg.norm(dp), atol=1e-8)
    assert np.allclose(np.cross(u, theta[0]), phi[0])  # (u, theta-hat, phi-hat) right-handed
    pole_theta, pole_phi = edges.polarisation_basis(np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]))
    assert np.allclose(pole_theta, [[1, 0, 0], [-1, 0, 0]]) and np.allclose(pole_phi, [[0, 1, 0], [0, 1, 0]])


def test_default_is_unchanged_and_po_is_polarisation_blind():
    mesh = trimesh.creation.box((0.3, 0.2, 0.1))
    a, p = np.radians([0, 30, 90, 180]), np.radians([0, 45, 200])
    default = simulate(mesh, a, p, F)
    assert default.shape == (4, 3, 3)
    assert np.array_equal(simulate(mesh, a, p, F, polarization="VV"), default)
    full = simulate(mesh, a, p, F, polarization="all")
    assert full.shape == (4, 3, 3, 4)
    vv, vh, hv, hh = np.moveaxis(full, -1, 0)
    assert np.array_equal(vv, default) and np.array_equal(hh, default)
    assert not vh.any() and not hv.any()
    assert np.array_equal(simulate(mesh, a, p, F, polarization=["hh"])[..., 0], default)


def test_edges_make_hh_differ_from_vv_and_stay_reciprocal():
    """Off the principal planes edge currents give cross-polarisation, with HV = VH."""
    a, p = np.radians([20, 50, 75]), np.radians([10, 35, 60])
    s = simulate(tilted_plate(), a, p, F, method="po+ec", polarization="all", dtype=np.complex128)
    vv, vh, hv, hh = np.moveaxis(s, -1, 0)
    assert np.abs(vh).max() > 1e-3 * np.abs(vv).max()
    assert np.allclose(vh, hv, rtol=0, atol=1e-12 * np.abs(vv).max())
    assert np.abs(hh - vv).max() > 1e-2 * np.abs(vv).max()


def test_cross_pol_vanishes_in_the_principal_planes():
    mesh = plate(0.2, 0.3)  # in the x-y plane, edges along x and y
    a = np.radians([10, 40, 70, 89])
    for roll in (0.0, np.pi / 2):
        s = simulate(mesh, a, [roll], F, method="po+ec", polarization=("HV", "VH", "VV"), dtype=np.complex128)
        assert np.abs(s[..., :2]).max() < 1e-12 * np.abs(s[..., 2]).max()


def test_rotation_about_the_look_direction():
    """Seen from +z (aspect 0, basis x, y), turning the body by chi about z turns the scattering
    matrix: S(chi) = R S(0) R^T with R the rotation by chi in the (V, H) = (x, y) basis."""
    chi = np.radians(30)
    mesh = tilted_plate().apply_transform(trimesh.transformations.rotation_matrix(np.radians(20), [0, 0, 1]))
    turned = mesh.copy().apply_transform(trimesh.transformations.rotation_matrix(chi, [0, 0, 1]))
    s0 = simulate(mesh, [0.0], [0.0], F, method="po+ec", polarization="all", dtype=np.complex128)[0, 0]
    s1 = simulate(turned, [0.0], [0.0], F, method="po+ec", polarization="all", dtype=np.complex128)[0, 0]
    r = np.array([[np.cos(chi), -np.sin(chi)], [np.sin(chi), np.cos(chi)]])
    m0, m1 = s0.reshape(-1, 2, 2), s1.reshape(-1, 2, 2)  # [transmit, receive]
    expected = r @ m0 @ r.T
    assert np.abs(m0[:, 0, 1]).max() > 1e-3 * np.abs(m0).max()  # a real cross-polarised return
    assert np.allclose(m1, expected, rtol=0, atol=1e-9 * np.abs(m0).max())


def test_bad_polarization_and_method():
    mesh = trimesh.creation.box()
    for bad in ("XY", "", [], ["VV", "XX"], 3):
        with pytest.raises(UserInputError, match="polarization"):
            simulate(mesh, [0.0], [0.0], [1e9], polarization=bad)
    with pytest.raises(UserInputError, match="method"):
        simulate(mesh, [0.0], [0.0], [1e9], method="po+sbr")
    with pytest.raises(UserInputError, match="edge_threshold_deg"):
        simulate(mesh, [0.0], [0.0], [1e9], method="po+ec", edge_threshold_deg=0.0)
    for bad in (-0.5, float("nan"), "x"):
        with pytest.raises(UserInputError, match="edge_krho"):
            simulate(mesh, [0.0], [0.0], [1e9], method="po+ec", edge_krho=bad)


def test_file_round_trip_and_old_files(tmp_path):
    s = np.ones((2, 3, 4, 4), dtype=np.complex64)
    axes = (np.zeros(2), np.zeros(3), np.ones(4))
    save_response(tmp_path / "all.npz", s, *axes, polarization=edges.ALL_POLARIZATIONS)
    loaded = load_response(tmp_path / "all.npz")
    assert loaded.polarization == ("VV", "VH", "HV", "HH") and loaded.response.shape == (2, 3, 4, 4)
    save_response(tmp_path / "hh.npz", s[..., 0], *axes, polarization="HH")
    assert load_response(tmp_path / "hh.npz").polarization == ("HH",)
    np.savez(tmp_path / "old.npz", response=s[..., 0], aspect_rad=axes[0], roll_rad=axes[1], freq_hz=axes[2])
    assert load_response(tmp_path / "old.npz").polarization == ("VV",)
    save_response(tmp_path / "plain.npz", s[..., 0], *axes)
    assert "polarization" not in np.load(tmp_path / "plain.npz").files  # default files as before
    with pytest.raises(UserInputError, match="polarization"):
        save_response(tmp_path / "bad.npz", s, *axes, polarization="VV")  # 4 channels, one name
    with pytest.raises(UserInputError, match="polarization"):
        save_response(tmp_path / "bad.npz", s[..., 0], *axes, polarization="XX")


def run_cli(*argv):
    parser = argparse.ArgumentParser()
    command.configure_parser(parser)
    return command.main(parser.parse_args([str(a) for a in argv]))


def test_cli_method_and_pol(tmp_path):
    mesh_file = tmp_path / "box.obj"
    trimesh.creation.box((2.0, 1.0, 0.5)).export(mesh_file)
    grid = ["--aspect-deg", "10:80:3", "--roll-deg", "0:40:2", "--freq-ghz", "8:12:3", "--size-m", "0.3"]
    assert run_cli(mesh_file, "--out", tmp_path / "hh.npz", "--method", "po+ec", "--pol", "HH", *grid) == 0
    hh = load_response(tmp_path / "hh.npz")
    assert hh.polarization == ("HH",) and hh.response.shape == (3, 2, 3)
    assert run_cli(mesh_file, "--out", tmp_path / "all.npz", "--method", "po+ec", "--pol", "all", *grid) == 0
    full = load_response(tmp_path / "all.npz")
    assert full.polarization == edges.ALL_POLARIZATIONS and full.response.shape == (3, 2, 3, 4)
    assert np.allclose(full.response[..., 3], hh.response)
    assert not np.allclose(full.response[..., 0], hh.response)  # edges: VV differs from HH


def test_config_accepts_polarization_and_edges():
    from data_modules.config import BuildConfig

    config = BuildConfig(family="frusta", num=2, simulator={"method": "po+ec", "polarization": "HH"})
    assert config.simulator["polarization"] == "HH"
    with pytest.raises(UserInputError, match="polarization"):
        BuildConfig(family="frusta", num=2, simulator={"polarization": "all"})
    with pytest.raises(UserInputError, match="method"):
        BuildConfig(family="frusta", num=2, simulator={"method": "ec"})
