"""CheckpointModel: a trained checkpoint scored on a dataset whose dB statistics differ from its training set's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from dataclasses import replace

from test_pretrained import tiny  # noqa: F401  (module fixture: a Trainer-saved tiny RadarDiffusion and its export)
from models.test_radar_diffusion import single_thread  # noqa: F401
from radar2shape.errors import UserInputError
from radar2shape.models.checkpoint_model import CheckpointModel, check_same_grid, renormalise
from radar2shape.radar.grid import RadarGrid
from radar2shape.radar.spec import RadarSpec


def spec(mean: float, std: float, freq=(8e9, 12e9, 8)) -> RadarSpec:
    grid = RadarGrid(np.linspace(0, np.pi, 4), np.linspace(0, 2 * np.pi, 8, endpoint=False), np.linspace(*freq), 1.0)
    return RadarSpec(grid, mean, std)


def test_renormalise_matches_hand_values():
    source, target = spec(-50.0, 10.0), spec(-40.0, 20.0)
    radar = torch.tensor([[[[1.0, -1.0, 3.0]]]])  # dB -40, -60, -20 under the source statistics
    mask = torch.tensor([[[True]]])
    out = renormalise(radar, mask, source, target)
    assert out.flatten().tolist() == pytest.approx([0.0, -1.0, 1.0])
    assert renormalise(radar, ~mask, source, target).abs().max() == 0  # masked cells stay at the train mean


def test_other_grid_is_refused_naming_the_axis():
    with pytest.raises(UserInputError, match="freq_hz") as err:
        check_same_grid(spec(-50, 10, freq=(8e9, 12e9, 16)), spec(-50, 10), "model.ckpt")
    assert "\n" not in str(err.value)
    check_same_grid(spec(-60, 5), spec(-50, 10), "model.ckpt")  # statistics may differ: renormalised


def test_scores_the_checkpoint_exactly_as_reconstruct_does(tiny, single_thread):  # noqa: F811
    wrapped = CheckpointModel(ckpt=str(tiny.exported))
    model_spec = wrapped.inner.radar_spec
    data_spec = replace(model_spec, db_mean=model_spec.db_mean - 7.0, db_std=model_spec.db_std * 1.5)
    wrapped._data_spec = data_spec
    rng = np.random.default_rng(3)
    db = rng.normal(model_spec.db_mean, model_spec.db_std, size=(2, 4, 8, 8))
    mask = rng.random((2, 4, 8)) > 0.3
    as_data = {"radar": torch.from_numpy(np.stack([data_spec.normalise(d, m) for d, m in zip(db, mask)])),
               "radar_mask": torch.from_numpy(mask), "index": torch.arange(2)}
    as_model = {**as_data, "radar": torch.from_numpy(np.stack([model_spec.normalise(d, m) for d, m in zip(db, mask)]))}
    torch.testing.assert_close(wrapped._model_batch(as_data)["radar"], as_model["radar"], atol=1e-5, rtol=0)
    got, want = wrapped.reconstruct(as_data), wrapped.inner.reconstruct(as_model)
    for a, b in zip(got, want):
        np.testing.assert_allclose(a.mesh.vertices, b.mesh.vertices, atol=1e-4)


def test_surface_level_override_moves_the_meshed_level(tiny, single_thread):  # noqa: F811
    """``surface_level`` reaches Stage 1: the SDF the model meshes is the stored one minus the level."""
    plain, shifted = CheckpointModel(ckpt=str(tiny.exported)), CheckpointModel(ckpt=str(tiny.exported), surface_level=0.01)
    assert plain.inner.stage1.hparams.surface_level == 0.0 and shifted.inner.stage1.hparams.surface_level == 0.01
    h = torch.zeros(2, plain.inner.n_levels, plain.inner.latent_dim)
    points = torch.rand(7, 3) - 0.5
    torch.testing.assert_close(shifted.inner.sdf_function(h)(points), plain.inner.sdf_function(h)(points) - 0.01)


def test_mesh_resolution_override_meshes_on_that_grid(tiny, single_thread):  # noqa: F811
    """``mesh_resolution`` is the grid of the reconstruction: the mesh ``mean_mesh`` gives at that resolution."""
    wrapped = CheckpointModel(ckpt=str(tiny.exported), mesh_resolution=24)
    assert wrapped.inner.hparams.mesh_resolution == 24
    h = torch.randn(1, 1, wrapped.inner.n_levels, wrapped.inner.latent_dim, generator=torch.Generator().manual_seed(1))
    wrapped.inner.sample_latents = lambda batch, **kwargs: h  # the same latent for both paths
    got = wrapped.inner.reconstruct({"radar": None})[0].mesh
    want, _ = wrapped.inner.mean_mesh(h[0], 24)
    other, _ = wrapped.inner.mean_mesh(h[0], 12)
    np.testing.assert_array_equal(got.vertices, want.vertices)
    assert len(want.vertices) != len(other.vertices)
    with pytest.raises(UserInputError, match="mesh_resolution: expected an integer >= 2, got 1"):
        CheckpointModel(ckpt=str(tiny.exported), mesh_resolution=1)


def test_a_verifier_returns_the_mean_of_its_best_scored_candidates(tiny, tmp_path, single_thread):  # noqa: F811
    """With a verifier the reconstruction of each input is the mean SDF of the ``keep`` best-scored of K
    samples drawn for that input alone, carrying their mean predicted IoU, as ``reconstruct --candidates``."""
    from test_reconstruct_cli import volume_verifier

    from radar2shape.models.verifier import default_verifier_path, save_verifier, score_candidates

    plain = CheckpointModel(ckpt=str(tiny.exported))
    verifier = volume_verifier(plain.inner)
    save_verifier(verifier, default_verifier_path(tiny.exported), plain.inner.n_levels, {"candidates": 4})
    try:
        wrapped = CheckpointModel(ckpt=str(tiny.exported), verifier="beside", candidates=4, keep=2)
        spec_ = wrapped.inner.radar_spec
        wrapped._data_spec = spec_
        rng = np.random.default_rng(5)
        db = rng.normal(spec_.db_mean, spec_.db_std, size=(2, 4, 8, 8))
        mask = np.ones((2, 4, 8), dtype=bool)
        batch = {"radar": torch.from_numpy(np.stack([spec_.normalise(d, m) for d, m in zip(db, mask)])).float(),
                 "radar_mask": torch.from_numpy(mask)}
        got = wrapped.reconstruct(batch)
        for i, recon in enumerate(got):
            one = {key: batch[key][i:i + 1] for key in batch}
            latents, predicted = score_candidates(wrapped.inner, verifier, one, 4)
            top = predicted.argsort(descending=True)[:2]
            want, _ = wrapped.inner.mean_mesh(latents[top])
            np.testing.assert_allclose(recon.mesh.vertices, want.vertices, atol=1e-5)
            assert recon.predicted_iou == pytest.approx(float(predicted[top].mean()), abs=1e-6)
        for bad, message in (({"keep": 5}, "keep: expected 1 to candidates \\(4\\), got 5"),
                             ({"candidates": 8}, "trained to choose among K = 4 candidates, not 8"),
                             ({"verifier": str(tmp_path / "none.pt")}, "no verifier file")):
            with pytest.raises(UserInputError, match=message):
                CheckpointModel(ckpt=str(tiny.exported), **{"verifier": "beside", "candidates": 4, **bad})
    finally:
        default_verifier_path(tiny.exported).unlink()


def test_fit_is_refused(tiny):  # noqa: F811
    wrapped = CheckpointModel(ckpt=str(tiny.exported))
    with pytest.raises(UserInputError, match="radar2shape test"):
        wrapped.setup("fit")


def test_bad_checkpoint_is_one_line(tmp_path):
    text = tmp_path / "notes.ckpt"
    text.write_text("not a checkpoint")
    with pytest.raises(UserInputError, match="model.init_args.ckpt") as err:
        CheckpointModel(ckpt=str(text))
    assert "\n" not in str(err.value)


def test_radar2shape_test_scores_a_checkpoint_through_the_cli(tiny, tmp_path, single_thread):  # noqa: F811
    """`radar2shape test --model CheckpointModel` on a dataset of the checkpoint's grid: every test shape
    scored with the diagnostics (the CLI builds the class inside its hyperparameter context)."""
    import csv

    import yaml

    from data_modules.build import build_dataset
    from data_modules.config import load_build_config
    from radar2shape.cli import main

    radar = tmp_path / "radar.yaml"
    radar.write_text(yaml.safe_dump({"aspect_deg": {"start": 0.0, "stop": 180.0, "count": 4},
                                     "roll_deg": {"start": 0.0, "stop": 360.0, "count": 8, "endpoint": False},
                                     "freq_ghz": {"start": 8.0, "stop": 12.0, "count": 8}, "size_m": 1.0}))
    config = tmp_path / "data.yaml"
    config.write_text(yaml.safe_dump({"family": "parts", "family_options": {"segments": 12}, "seed": 0, "num": 6,
                                      "splits": {"train": 3, "val": 1, "test": 2},
                                      "mesh": {"face_budget": 2000, "remesh_resolution": 48},
                                      "sampling": {"surface": 512, "eval": 512, "sdf": 512, "occ": 1024},
                                      "radar": str(radar)}))
    root = tmp_path / "data"
    build_dataset(load_build_config(config), root, progress=False)
    repo = Path(__file__).resolve().parents[2]
    code = main(["test", "--config", str(repo / "conf/trainer/cpu.yaml"), "--config", str(repo / "conf/callbacks/shape_metrics.yaml"),
                 "--model=radar2shape.models.checkpoint_model.CheckpointModel", f"--model.init_args.ckpt={tiny.exported}",
                 "--data=data_modules.ShapeDataModule", f"--data.init_args.root={root}", "--data.init_args.observability=full",
                 "--data.init_args.batch_size=2", f"--trainer.default_root_dir={tmp_path / 'run'}"])
    assert code == 0
    rows = list(csv.DictReader((tmp_path / "run/version_0/metrics.csv").open()))
    logged = {k: float(v) for row in rows for k, v in row.items() if v != ""}
    assert logged["test/iou_count"] == 2 and "test/radar_dependence_iou_mean" in logged and "test/ceiling_iou_mean" in logged
