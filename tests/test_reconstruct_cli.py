"""``radar2shape reconstruct``: bad response files fail with one clear line; good ones give a mesh."""

from __future__ import annotations

import numpy as np
import pytest

from models.test_radar_diffusion import (  # noqa: F401  (single_thread: the module's fixture)
    save_checkpoint,
    single_thread,
    sphere_batch,
    sphere_stage1,
    tiny_model,
)
from radar2shape.cli import main
from radar2shape.radar import save_response

ASPECT = np.linspace(0, np.pi, 4)
ROLL = np.linspace(0, 2 * np.pi, 8, endpoint=False)
FREQ = np.linspace(8e9, 12e9, 8)


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory, single_thread) -> str:
    """A tiny RadarDiffusion on a 4 x 8 x 8 grid whose Stage 1 decodes a sphere."""
    folder = tmp_path_factory.mktemp("reconstruct")
    model = tiny_model(sphere_stage1(folder / "stage1.ckpt"), sample_steps=10)
    model.standardiser.fit(model.stage1.encode(sphere_batch()["surface_points"])[0])
    model.hparams.radar_meta = {"aspect_rad": ASPECT.tolist(), "roll_rad": ROLL.tolist(), "freq_hz": FREQ.tolist(),
                                "db_mean": -30.0, "db_std": 10.0, "floor_db": -100.0}
    return save_checkpoint(model, folder / "stage2.ckpt")


def response_file(path, aspect=ASPECT, roll=ROLL, freq=FREQ, **replace) -> str:
    rng = np.random.default_rng(0)
    shape = (len(aspect), len(roll), len(freq))
    fields = {"response": (rng.normal(size=shape) + 1j * rng.normal(size=shape)).astype(np.complex64),
              "aspect_rad": aspect, "roll_rad": roll, "freq_hz": freq, **replace}
    np.savez(path, **{k: v for k, v in fields.items() if v is not None})
    return str(path)


def run(checkpoint, radar, out, *extra) -> int:
    return main(["reconstruct", "--ckpt", checkpoint, "--radar", radar, "--out", str(out), *extra])


def test_valid_file_runs_end_to_end(checkpoint, tmp_path, capsys):
    radar = tmp_path / "r.npz"
    save_response(radar, np.ones((4, 8, 8), np.complex64) * 0.1, ASPECT, ROLL, FREQ)
    out, png, spread = tmp_path / "mesh.obj", tmp_path / "view.png", tmp_path / "spread.npy"
    assert run(checkpoint, str(radar), out, "--samples", "2", "--steps", "5", "--png", str(png),
               "--spread", str(spread)) == 0
    assert out.stat().st_size > 0 and png.stat().st_size > 0
    assert "vertices" in capsys.readouterr().out
    assert np.load(spread).ndim == 1 and len(np.load(spread)) > 0


def test_other_grid_is_resampled(checkpoint, tmp_path):
    radar = response_file(tmp_path / "fine.npz", aspect=np.linspace(0, np.pi, 7),
                          roll=np.linspace(0.1, 0.1 + 2 * np.pi, 12, endpoint=False), freq=np.linspace(7e9, 13e9, 5))
    assert run(checkpoint, radar, tmp_path / "m.obj", "--steps", "3") == 0


@pytest.mark.parametrize(
    "replace, message",
    [
        ({"freq_hz": None}, "missing array"),
        ({"roll_rad": None}, "roll_rad"),
        ({"response": np.full((4, 8, 8), np.nan, np.complex64)}, "NaN"),
        ({"aspect_rad": np.linspace(0, np.pi, 5)}, "aspect_rad"),
        ({"freq_hz": np.linspace(11e9, 14e9, 8)}, "covers 25 % of the model's 8-12 GHz"),
        ({"aspect_rad": np.array([0.0, 1.0, 1.0, np.pi])}, "'aspect_rad'[2] = 1 duplicates"),
        ({"response": np.ones((4, 1, 8), np.complex64), "roll_rad": np.zeros(1)}, "--roll-symmetric"),
    ],
)
def test_bad_files_give_one_line_errors(checkpoint, tmp_path, capsys, replace, message):
    assert run(checkpoint, response_file(tmp_path / "bad.npz", **replace), tmp_path / "m.obj") == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and message in err and "\n" not in err


def test_missing_checkpoint_and_bad_options(checkpoint, tmp_path, capsys):
    radar = response_file(tmp_path / "r.npz")
    assert run(str(tmp_path / "none.ckpt"), radar, tmp_path / "m.obj") == 2
    assert run(checkpoint, radar, tmp_path / "m.obj", "--steps", "1000") == 2
    assert "--steps" in capsys.readouterr().err
