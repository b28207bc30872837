"""CheckpointModel: a trained checkpoint scored on a dataset whose dB statistics differ from its training set's."""

from __future__ import annotations

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
    model_spec = wrapped.load().radar_spec
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


def test_fit_is_refused(tiny):  # noqa: F811
    wrapped = CheckpointModel(ckpt=str(tiny.exported))
    with pytest.raises(UserInputError, match="radar2shape test"):
        wrapped.setup("fit")


def test_bad_checkpoint_is_one_line(tmp_path):
    text = tmp_path / "notes.ckpt"
    text.write_text("not a checkpoint")
    with pytest.raises(UserInputError, match="model.init_args.ckpt") as err:
        CheckpointModel(ckpt=str(text)).load()
    assert "\n" not in str(err.value)
