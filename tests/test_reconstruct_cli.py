"""``radar2shape reconstruct``: bad response files fail with one clear line; good ones give a mesh.

The radar spec (grid + dB normalisation) comes from the checkpoint alone: models fitted on tiny
built datasets reconstruct after the dataset is deleted, exactly as the model does in memory.
"""

from __future__ import annotations

import shutil

import lightning as L
import numpy as np
import pytest
import torch
import trimesh

from data.conftest import tiny_config
from data_modules import ProfileDataModule, ShapeDataModule
from data_modules.build import build_dataset
from models.test_radar_diffusion import (  # noqa: F401  (single_thread: the module's fixture)
    single_thread,
    sphere_batch,
    sphere_stage1,
    tiny_model,
)
from radar2shape.cli import main
from radar2shape.errors import UserInputError
from radar2shape.models.profile_diffusion import ProfileUNetDiffusion
from radar2shape.models.radar_diffusion import RadarDiffusion
from radar2shape.radar import RadarGrid, save_response
from radar2shape.radar.spec import RadarSpec

ASPECT = np.linspace(0, np.pi, 4)
ROLL = np.linspace(0, 2 * np.pi, 8, endpoint=False)
FREQ = np.linspace(8e9, 12e9, 8)
SPEC = RadarSpec(RadarGrid(ASPECT, ROLL, FREQ), db_mean=-30.0, db_std=10.0, floor_db=-100.0)
SMALL_POINTS = {split: {"surface": 64, "sdf": 128, "eval": 0, "occ": 0} for split in ("train", "val", "test")}


def save_with_spec(model: L.LightningModule, path) -> str:
    """A Lightning-format checkpoint with what the model's checkpoint hook adds (its radar spec)."""
    checkpoint = {"state_dict": model.state_dict(), "hyper_parameters": dict(model.hparams),
                  "pytorch-lightning_version": L.__version__}
    model.on_save_checkpoint(checkpoint)
    torch.save(checkpoint, path)
    return str(path)


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory, single_thread) -> str:
    """A tiny RadarDiffusion on a 4 x 8 x 8 grid whose Stage 1 decodes a sphere."""
    folder = tmp_path_factory.mktemp("reconstruct")
    model = tiny_model(sphere_stage1(folder / "stage1.ckpt"), sample_steps=10)
    model.standardiser.fit(model.stage1.encode(sphere_batch()["surface_points"])[0])
    model.set_radar_spec(SPEC)
    return save_with_spec(model, folder / "stage2.ckpt")


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
    printed = capsys.readouterr().out
    assert "vertices" in printed
    # The printed confidence is the residual of the written mesh against the input (recomputed here).
    import trimesh

    from radar2shape.commands.reconstruct import load_model
    from radar2shape.metrics.consistency import radar_consistency

    spec = load_model(checkpoint).radar_spec
    db = spec.to_db(np.ones((4, 8, 8), np.complex64) * 0.1)
    expected = radar_consistency(trimesh.load(out, process=False), db, np.ones((4, 8), bool), spec)
    assert f"radar consistency: {expected:.3f} " in printed and 0 <= expected <= 1
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


def test_checkpoint_without_radar_spec_is_refused(checkpoint, tmp_path, capsys):
    old = torch.load(checkpoint, weights_only=True)
    del old["radar_spec"]
    old["hyper_parameters"]["radar_meta"] = SPEC.to_dict()  # what checkpoints held before
    torch.save(old, tmp_path / "old.ckpt")
    assert run(str(tmp_path / "old.ckpt"), response_file(tmp_path / "r.npz"), tmp_path / "m.obj") == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: --ckpt: {tmp_path / 'old.ckpt'} stores no radar spec") and "retrain" in err
    assert "\n" not in err


def fit(model, datamodule, root) -> str:
    """Two training steps through a Trainer; the checkpoint it saves."""
    trainer = L.Trainer(max_steps=2, logger=False, enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False, accelerator="cpu", default_root_dir=root, limit_val_batches=0)
    trainer.fit(model, datamodule=datamodule)
    trainer.save_checkpoint(root / "model.ckpt")
    return str(root / "model.ckpt")


@pytest.fixture(scope="module")
def fitted(tmp_path_factory, single_thread):
    """Tiny 3D and profile models fitted on tiny built datasets, which are then deleted.

    Returns ``{kind: (checkpoint, spec, complex response of a test record)}``.
    """
    out = {}
    for kind, family in (("3d", "parts"), ("profile", "frusta")):
        root = tmp_path_factory.mktemp(kind)
        data = root / "data"
        build_dataset(tiny_config(family, 5), data, progress=False)
        if kind == "3d":
            datamodule = ShapeDataModule(str(data), batch_size=2, points=SMALL_POINTS, floor_db=-80.0)
            model = tiny_model(sphere_stage1(root / "stage1.ckpt"), num_freq=16, sample_steps=4)
        else:
            datamodule = ProfileDataModule(str(data), batch_size=2, points=SMALL_POINTS)
            torch.manual_seed(0)
            model = ProfileUNetDiffusion(num_aspect=16, num_freq=16, profile_points=datamodule.profile_points,
                                         profile_channels=4, base_channels=8, depth=1, time_dim=16, out_channels=4,
                                         num_steps=10)
            model.hparams["_class_path"] = "radar2shape.models.profile_diffusion.ProfileUNetDiffusion"  # as the CLI saves
        response = datamodule.records("test")[0]["radar"]
        out[kind] = (fit(model, datamodule, root), datamodule.radar_spec, response)
        shutil.rmtree(data)
    return out


def test_3d_model_reconstructs_from_its_checkpoint_alone(fitted, tmp_path):
    ckpt, spec, response = fitted["3d"]
    assert spec.floor_db == -80.0 and not spec.roll_symmetric  # the DataModule's, not a default
    radar, out, saved = tmp_path / "r.npz", tmp_path / "m.obj", tmp_path / "input.npz"
    save_response(radar, response, *(getattr(spec.grid, a) for a in ("aspect_rad", "roll_rad", "freq_hz")))
    assert run(ckpt, str(radar), out, "--save-input", str(saved)) == 0
    expected = spec.normalise(spec.to_db(response))  # every cell observed
    np.testing.assert_allclose(np.load(saved)["radar"], expected, atol=1e-5)
    model = RadarDiffusion.load_from_checkpoint(ckpt, map_location="cpu", weights_only=True).eval()
    assert model.radar_spec == spec
    batch = {"radar": torch.from_numpy(expected)[None], "radar_mask": torch.ones(1, *spec.input_shape[:2], dtype=torch.bool)}
    mesh = model.reconstruct(batch)[0].mesh
    written = trimesh.load(out, force="mesh", process=False)
    assert len(mesh.faces) > 0 and written.faces.shape == mesh.faces.shape
    np.testing.assert_allclose(written.vertices, mesh.vertices, atol=1e-5)


def test_profile_model_reconstructs_from_its_checkpoint_alone(fitted, tmp_path):
    ckpt, spec, response = fitted["profile"]
    assert spec.roll_symmetric and spec.input_shape == (16, 16)
    radar, out = tmp_path / "r.npz", tmp_path / "p.obj"
    save_response(radar, response[:, :1], spec.grid.aspect_rad, spec.grid.roll_rad, spec.grid.freq_hz)
    assert run(ckpt, str(radar), out) == 0
    model = ProfileUNetDiffusion.load_from_checkpoint(ckpt, map_location="cpu", weights_only=True).eval()
    assert model.radar_spec == spec
    expected = spec.normalise(spec.to_db(response[:, 0]))
    recon = model.reconstruct({"radar": torch.from_numpy(expected)[None], "radar_mask": torch.ones(1, 16, dtype=torch.bool)})[0]
    written = trimesh.load(out, force="mesh", process=False)
    assert written.faces.shape == recon.mesh.faces.shape
    np.testing.assert_allclose(written.vertices, recon.mesh.vertices, atol=1e-5)


def test_a_datamodule_that_does_not_fit_the_network_is_refused(fitted, checkpoint):
    profile_spec = fitted["profile"][1]
    model = RadarDiffusion.load_from_checkpoint(checkpoint, map_location="cpu", weights_only=True)
    with pytest.raises(UserInputError, match=r"RadarDiffusion: expects \[A, R, F=8\] radar.*16 x 16"):
        model.set_radar_spec(profile_spec)
    profile = ProfileUNetDiffusion(num_aspect=16, num_freq=8, profile_points=16)
    with pytest.raises(UserInputError, match=r"roll-symmetric radar \[A=16, F=8\]"):
        profile.set_radar_spec(profile_spec)
    with pytest.raises(UserInputError, match="roll-symmetric"):
        ProfileUNetDiffusion(num_aspect=4, num_freq=8).set_radar_spec(SPEC)
    ProfileUNetDiffusion(num_aspect=16, num_freq=16).set_radar_spec(profile_spec)  # fits: accepted


def volume_verifier(model):
    """A verifier file's model that scores candidates by their volume (a known, checkable rule)."""
    from radar2shape.models.verifier import Verifier, feature_names

    names = feature_names(model.n_levels)
    verifier = Verifier(len(names), hidden=4)
    with torch.no_grad():
        for p in verifier.parameters():
            p.zero_()
        verifier.net[0].weight[0, names.index("log_volume_ratio")] = 1.0
        verifier.net[0].bias[0] = 5.0
        verifier.net[2].weight[0, 0] = 1.0
        verifier.net[4].weight[0, 0] = 1.0
    return verifier


def test_candidates_return_the_verified_sample(checkpoint, tmp_path, capsys):
    from radar2shape.commands.reconstruct import load_model, measured_input, model_batch
    from radar2shape.models.verifier import default_verifier_path, save_verifier, score_candidates

    model = load_model(checkpoint)
    verifier = volume_verifier(model)
    path = tmp_path / "volume.verifier.pt"
    save_verifier(verifier, path, model.n_levels, {"rule": "volume"})
    radar = response_file(tmp_path / "r.npz")
    out = tmp_path / "m.obj"
    assert run(checkpoint, radar, out, "--candidates", "4", "--keep", "1", "--steps", "3", "--seed", "2",
               "--verifier", str(path)) == 0
    printed = capsys.readouterr().out
    grid = measured_input([tmp_path / "r.npz"], "npz", model.radar_spec)
    latents, predicted = score_candidates(model, verifier, model_batch(model.radar_spec, grid), 4, 3, 2)
    order = [int(i) for i in predicted.argsort(descending=True)]
    best = order[0]
    assert f"verifier: returned candidate {best + 1} of 4, predicted IoU {float(predicted[best]):.2f} " in printed
    expected = model.mean_mesh(latents[best:best + 1])[0]
    assert len(trimesh.load(out, process=False).vertices) == len(expected.vertices)
    # by default the mean SDF of the best three, with the mean of their predicted IoUs
    assert run(checkpoint, radar, out, "--candidates", "4", "--steps", "3", "--seed", "2", "--verifier", str(path)) == 0
    printed = capsys.readouterr().out
    top = order[:3]
    assert (f"verifier: returned the mean of candidates {', '.join(str(i + 1) for i in top)} (its best 3) of 4, "
            f"predicted IoU {float(predicted[top].mean()):.2f} ") in printed
    expected = model.mean_mesh(latents[top])[0]
    assert len(trimesh.load(out, process=False).vertices) == len(expected.vertices)
    # the default verifier lives beside the checkpoint: absent there, one line says where it looked
    copy = tmp_path / "model.ckpt"
    shutil.copy(checkpoint, copy)
    assert run(str(copy), radar, tmp_path / "m2.obj", "--candidates", "2") == 2
    err = capsys.readouterr().err.strip()
    assert f"no verifier beside model.ckpt: expected {default_verifier_path(copy)}" in err and "\n" not in err
    shutil.copy(path, default_verifier_path(copy))
    assert run(str(copy), radar, tmp_path / "m2.obj", "--candidates", "2", "--steps", "3") == 0
    # a verifier trained for another K is refused in one line, before any sampling
    save_verifier(verifier, path, model.n_levels, {"candidates": 8})
    capsys.readouterr()
    assert run(checkpoint, radar, tmp_path / "m3.obj", "--candidates", "3", "--verifier", str(path)) == 2
    err = capsys.readouterr().err.strip()
    assert "trained to choose among K = 8 candidates, not 3" in err and "\n" not in err
    assert not (tmp_path / "m3.obj").exists()


@pytest.mark.parametrize("extra, message", [
    (["--candidates", "1"], "--candidates: expected an integer >= 2, got 1"),
    (["--candidates", "2", "--samples", "2"], "use one of them"),
    (["--verifier", "v.pt"], "--verifier is read with --candidates K"),
    (["--keep", "2"], "--keep is read with --candidates K"),
    (["--candidates", "3", "--keep", "4"], "--keep: at most the 3 candidates, got 4"),
    (["--candidates", "3", "--keep", "0"], "--keep: expected a positive integer, got 0"),
])
def test_bad_candidate_options(checkpoint, tmp_path, capsys, extra, message):
    assert run(checkpoint, response_file(tmp_path / "r.npz"), tmp_path / "m.obj", *extra) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and not (tmp_path / "m.obj").exists()
