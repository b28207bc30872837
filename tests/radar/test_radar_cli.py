"""``radar2shape simulate`` through its main(args), as the console script calls it."""

import argparse

import numpy as np
import pytest
import trimesh

from radar2shape.commands import simulate as command
from radar2shape.errors import UserInputError
from radar2shape.radar import load_response


def run(*argv):
    parser = argparse.ArgumentParser()
    command.configure_parser(parser)
    return command.main(parser.parse_args([str(a) for a in argv]))


@pytest.fixture
def mesh_file(tmp_path):
    path = tmp_path / "box.obj"
    trimesh.creation.box((2.0, 1.0, 0.5)).export(path)
    return path


def test_simulate_writes_response_and_plot(mesh_file, tmp_path, capsys):
    out, png = tmp_path / "out" / "r.npz", tmp_path / "r.png"
    code = run(mesh_file, "--out", out, "--aspect-deg", "0:180:7", "--roll-deg", "0:90:3", "--freq-ghz", "8:12:4",
               "--size-m", "0.5", "--plot", png)
    assert code == 0 and png.stat().st_size > 1000
    loaded = load_response(out)
    assert loaded.response.shape == (7, 3, 4) and loaded.size_m == 0.5
    assert np.allclose(np.degrees(loaded.aspect_rad), np.linspace(0, 180, 7))
    # the 0.5 x 0.25 face (box rescaled by 1/4) seen face-on at aspect 0
    lam = 299_792_458.0 / loaded.freq_hz
    assert np.allclose(np.abs(loaded.response[0, 0]) ** 2, 4 * np.pi * 0.125**2 / lam**2, rtol=1e-4)
    assert "wrote" in capsys.readouterr().out


def test_grid_file_and_keep_size(mesh_file, tmp_path):
    out = tmp_path / "r.npz"
    run(mesh_file, "--out", out, "--grid", "conf/radar/tiny.yaml", "--keep-size", "--no-shadow")
    loaded = load_response(out)
    assert loaded.response.shape == (16, 16, 16) and loaded.size_m is None
    lam = 299_792_458.0 / loaded.freq_hz
    assert np.allclose(np.abs(loaded.response[0, 0]) ** 2, 4 * np.pi * 2.0**2 / lam**2, rtol=1e-4)


@pytest.mark.parametrize(
    "extra, match",
    [(["--aspect-deg", "0:190:3"], "aspect"), (["--freq-ghz", "0:10:3"], "positive"), (["--roll-deg", "0:1"], "START:STOP:COUNT"),
     (["--freq-ghz", "8:12:0"], "COUNT"), (["--size-m", "-1"], "size"), (["--method", "sbr", "--bounces", "0"], "max_bounces"),
     (["--method", "po+ec", "--edge-krho", "-1"], "edge_krho"), (["--method", "po+ec", "--edge-threshold-deg", "0"], "edge_threshold"),
     (["--method", "po+ec", "--edge-order", "3"], "edge_order")],
)
def test_bad_arguments(mesh_file, tmp_path, extra, match):
    with pytest.raises(UserInputError, match=match):
        run(mesh_file, "--out", tmp_path / "r.npz", "--freq-ghz", "8:12:2", *extra)


def test_not_a_mesh(tmp_path):
    bad = tmp_path / "bad.obj"
    bad.write_text("this is not a mesh\n")
    with pytest.raises(UserInputError):
        run(bad, "--out", tmp_path / "r.npz")
    with pytest.raises(UserInputError):
        run(tmp_path / "missing.stl", "--out", tmp_path / "r.npz")
