"""Inputs, grid/config, dB, noise, masks and the response file."""

from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

from radar2shape.errors import UserInputError
from radar2shape.radar import (RadarGrid, add_noise, fixed_window_mask, load_response, random_window_mask,
                               save_response, simulate, to_db)
from radar2shape.radar.facets import facet_mesh

CONF = Path(__file__).resolve().parents[2] / "conf" / "radar"
MESH = trimesh.creation.box((0.3, 0.2, 0.1))


@pytest.mark.parametrize(
    "mesh, match",
    [
        ("not a mesh", "expected a trimesh"),
        ((np.zeros((0, 3)), np.zeros((0, 3), int)), "empty"),
        ((np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), [[0, 1, 2]]), "NaN"),
        ((np.eye(3), [[0, 1, 5]]), "face indices"),
        ((np.eye(3), [[0.0, 1.0, 2.0]]), "integer"),
        ((np.zeros((3, 3)), [[0, 1, 2]]), "degenerate"),
    ],
)
def test_bad_meshes(mesh, match):
    with pytest.raises(UserInputError, match=match):
        simulate(mesh, [0.0], [0.0], [1e9])


@pytest.mark.parametrize(
    "aspect, freq, match",
    [([-0.1], [1e9], "aspect_rad"), ([3.2], [1e9], "aspect_rad"), ([0.1], [0.0], "positive"),
     ([0.1], [-1e9], "positive"), ([np.nan], [1e9], "NaN"), ([], [1e9], "non-empty")],
)
def test_bad_axes(aspect, freq, match):
    with pytest.raises(UserInputError, match=match):
        simulate(MESH, aspect, [0.0], freq)


def test_method_and_dtype_errors():
    with pytest.raises(UserInputError, match="max_bounces"):
        simulate(MESH, [0.0], [0.0], [1e9], method="sbr", max_bounces=0)
    with pytest.raises(UserInputError, match="method"):
        simulate(MESH, [0.0], [0.0], [1e9], method="mom")
    with pytest.raises(UserInputError, match="dtype"):
        simulate(MESH, [0.0], [0.0], [1e9], dtype=np.float32)


def test_degenerate_faces_are_dropped():
    box = trimesh.creation.box((0.3, 0.2, 0.1))
    faces = np.vstack([box.faces, [[0, 0, 1], [0, 1, 1]]])  # two zero-area faces
    assert facet_mesh((box.vertices, faces)).n_dropped == 2
    grid = dict(aspect_rad=np.linspace(0, np.pi, 5), roll_rad=[0.0, 1.0], freq_hz=[8e9, 9e9])
    assert np.array_equal(simulate((box.vertices, faces), **grid), simulate(box, **grid))


def test_output_shape_dtype_and_finite():
    grid = RadarGrid.from_yaml(CONF / "tiny.yaml")
    response = simulate(MESH, grid.aspect_rad, grid.roll_rad, grid.freq_hz)
    assert response.shape == grid.shape == (16, 16, 16)
    assert response.dtype == np.complex64 and np.isfinite(response).all()
    # the box's face-on returns at the poles: 4 pi A^2 / lambda^2 for the 0.3 x 0.2 face
    lam = 299_792_458.0 / grid.freq_hz
    assert np.allclose(np.abs(response[0, 0]) ** 2, 4 * np.pi * 0.06**2 / lam**2, rtol=1e-4)
    assert np.allclose(response[0, 0], response[0, 5])  # the pole is the same for every roll


def test_default_grid_matches_yaml():
    grid, default = RadarGrid.from_yaml(CONF / "default.yaml"), RadarGrid.default()
    for name in ("aspect_rad", "roll_rad", "freq_hz"):
        assert np.array_equal(getattr(grid, name), getattr(default, name))
    assert grid.shape == (32, 32, 64) and grid.size_m == 1.0
    assert grid.aspect_rad[0] == 0 and grid.aspect_rad[-1] == pytest.approx(np.pi)
    assert grid.roll_rad[-1] == pytest.approx(2 * np.pi * 31 / 32)
    assert grid.freq_hz[0] == pytest.approx(8e9) and grid.freq_hz[-1] == pytest.approx(12e9)
    again = RadarGrid.from_config(yaml.safe_load(yaml.safe_dump(grid.to_config())))
    assert np.allclose(again.roll_rad, grid.roll_rad) and again.size_m == grid.size_m


def test_grid_config_errors():
    with pytest.raises(UserInputError, match="unknown keys"):
        RadarGrid.from_config({"aspect": [0, 1]})
    with pytest.raises(UserInputError, match="count"):
        RadarGrid.from_config({"freq_ghz": {"start": 8, "stop": 12, "count": 0}})
    with pytest.raises(UserInputError, match="aspect_rad"):
        RadarGrid.from_config({"aspect_deg": [0, 200]})
    with pytest.raises(UserInputError, match="size_m"):
        RadarGrid.from_config({"size_m": -1})
    assert RadarGrid.from_config({"freq_ghz": [10.0]}).shape == (32, 32, 1)


def test_to_db_floor():
    out = to_db(np.array([0.0, 1.0, 10.0 + 0j]), floor_db=-100.0)
    assert np.allclose(out, [-100.0, 0.0, 20.0])


def test_add_noise_power_and_reproducibility():
    response = np.zeros((64, 64, 32), dtype=np.complex64)
    noisy = add_noise(response, -40.0, np.random.default_rng(0))
    assert noisy.dtype == np.complex64
    assert np.mean(np.abs(noisy) ** 2) == pytest.approx(1e-4, rel=0.02)  # absolute -40 dBsm
    assert np.mean(noisy.real**2) == pytest.approx(np.mean(noisy.imag**2), rel=0.05)  # circular
    assert np.array_equal(noisy, add_noise(response, -40.0, 0))  # an int seed means default_rng(seed)
    with pytest.raises(UserInputError):
        add_noise(np.zeros(3), -40.0, 0)


@pytest.mark.parametrize("seed", range(20))
def test_random_window_mask(seed):
    mask = random_window_mask(32, 32, 0.3, 1.0, np.random.default_rng(seed))
    assert mask.shape == (32, 32) and mask.dtype == bool
    aspect, roll = mask.any(axis=1), mask.any(axis=0)
    assert np.array_equal(mask, aspect[:, None] & roll[None, :])
    for axis, circular in ((aspect, False), (roll, True)):
        assert 0.3 <= axis.mean() <= 1.0
        rises = np.count_nonzero(np.diff(axis.astype(int), append=axis[0] if circular else 0) != 0)
        assert rises <= 2  # one contiguous window (roll may wrap)
    if not aspect.all():
        idx = np.flatnonzero(aspect)
        assert idx[-1] - idx[0] + 1 == len(idx)


def test_fixed_window_mask_is_reproducible_and_sized():
    a, b = fixed_window_mask(32, 32, 0.3, seed=1), fixed_window_mask(32, 32, 0.3, seed=1)
    assert np.array_equal(a, b)
    assert a.any(axis=1).sum() == 10 and a.any(axis=0).sum() == 10  # ceil(0.3 * 32)
    with pytest.raises(UserInputError):
        fixed_window_mask(32, 32, 0.0)


def test_response_file_round_trip(tmp_path):
    grid = RadarGrid.from_yaml(CONF / "tiny.yaml")
    response = (np.arange(np.prod(grid.shape)).reshape(grid.shape) * (1 + 1j)).astype(np.complex64)
    path = save_response(tmp_path / "r.npz", response, grid.aspect_rad, grid.roll_rad, grid.freq_hz, size_m=2.0)
    loaded = load_response(path)
    assert np.array_equal(loaded.response, response) and loaded.response.dtype == np.complex64
    assert np.array_equal(loaded.freq_hz, grid.freq_hz) and loaded.size_m == 2.0
    assert [p.name for p in tmp_path.iterdir()] == ["r.npz"]  # no temporary file left behind


def test_response_file_errors(tmp_path):
    axes = (np.zeros(2), np.zeros(3), np.ones(4))
    good = np.ones((2, 3, 4), np.complex64)
    with pytest.raises(UserInputError, match="not found"):
        load_response(tmp_path / "missing.npz")
    np.savez(tmp_path / "partial.npz", response=good, aspect_rad=axes[0])
    with pytest.raises(UserInputError, match="missing field"):
        load_response(tmp_path / "partial.npz")
    np.savez(tmp_path / "shape.npz", response=good, aspect_rad=axes[0], roll_rad=np.zeros(5), freq_hz=axes[2])
    with pytest.raises(UserInputError, match="roll_rad"):
        load_response(tmp_path / "shape.npz")
    bad = good.copy()
    bad[0, 0, 0] = np.nan
    np.savez(tmp_path / "nan.npz", response=bad, aspect_rad=axes[0], roll_rad=axes[1], freq_hz=axes[2])
    with pytest.raises(UserInputError, match="NaN"):
        load_response(tmp_path / "nan.npz")
    (tmp_path / "text.npz").write_text("hello")
    with pytest.raises(UserInputError, match="readable"):
        load_response(tmp_path / "text.npz")
    with pytest.raises(UserInputError, match="complex"):
        save_response(tmp_path / "real.npz", good.real, *axes)
