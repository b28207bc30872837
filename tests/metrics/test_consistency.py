"""Radar consistency: hand-computed residuals, and a shape that explains its radar better than another."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from radar2shape.metrics.consistency import power_residual, radar_consistency
from radar2shape.radar import RadarGrid, simulate, to_db
from radar2shape.radar.spec import RadarSpec


def db(power) -> np.ndarray:
    return 10 * np.log10(np.asarray(power, dtype=float)).reshape(1, 1, -1)


def test_power_residual_hand_values():
    mask = np.ones((1, 1), dtype=bool)
    assert power_residual(db([3.0, 6.0]), np.array([1.0, 2.0]).reshape(1, 1, 2), mask) == pytest.approx(0.0, abs=1e-12)
    assert power_residual(db([1.0, 1.0]), np.array([1.0, 0.0]).reshape(1, 1, 2), mask) == pytest.approx(1 / np.sqrt(2))
    assert power_residual(db([1.0, 1e-30]), np.array([0.0, 1.0]).reshape(1, 1, 2), mask) == pytest.approx(1.0)
    observed = db([1.0, 4.0]).repeat(2, axis=1)  # two roll cells; the second is masked and differs
    observed[0, 1] = db([100.0, 1.0])
    simulated = np.array([1.0, 4.0]).reshape(1, 1, 2).repeat(2, axis=1)
    assert power_residual(observed, simulated, np.array([[True, False]])) == pytest.approx(0.0, abs=1e-12)
    nan_cell = observed.copy()
    nan_cell[0, 0, 1] = np.nan  # a frequency without data is left out, not counted as zero power
    assert power_residual(nan_cell, simulated, np.array([[True, False]])) == pytest.approx(0.0, abs=1e-12)


def test_the_true_shape_explains_its_radar_better_than_another():
    grid = RadarGrid(np.linspace(0.2, np.pi - 0.2, 6), np.linspace(0, 2 * np.pi, 6, endpoint=False),
                     np.linspace(8e9, 12e9, 4), 1.0)
    spec = RadarSpec(grid, -20.0, 10.0)
    box = trimesh.creation.box(extents=(1.0, 0.6, 0.3))
    observed = to_db(simulate(box, grid.aspect_rad, grid.roll_rad, grid.freq_hz))
    mask = np.ones(observed.shape[:2], dtype=bool)
    own = radar_consistency(box, observed, mask, spec)
    sphere = radar_consistency(trimesh.creation.icosphere(3, radius=0.5), observed, mask, spec)
    assert own < 1e-3 < sphere


def test_the_evaluator_logs_consistency_per_shape_and_its_rank_correlation_with_iou(tmp_path):
    import csv

    import lightning as L
    import torch
    from scipy.stats import spearmanr
    from torch.utils.data import DataLoader

    from radar2shape.geometry.query import contains, sample_surface
    from radar2shape.metrics import ConsistencyScorer, ReconstructionEvaluator, ShapeScorer
    from radar2shape.metrics.functional import occupancy_points
    from radar2shape.models.base import Reconstruction, ReconstructionModel

    grid = RadarGrid(np.linspace(0.3, np.pi - 0.3, 4), np.linspace(0, 2 * np.pi, 4, endpoint=False),
                     np.linspace(8e9, 12e9, 3), 1.0)
    spec = RadarSpec(grid, -20.0, 10.0)
    truths = [trimesh.creation.box(extents=e) for e in ((0.8, 0.5, 0.3), (0.6, 0.6, 0.4), (0.9, 0.3, 0.3))]
    guesses = [truths[0].copy(), trimesh.creation.icosphere(2, radius=0.3), trimesh.creation.box(extents=(0.5,) * 3),
               trimesh.creation.icosphere(2, radius=0.25)]
    truths.append(truths[1])
    predicted = [0.9, 0.2, 0.6, 0.1]  # the model's own IoU estimates, logged beside the true IoU
    records = []
    for i, truth in enumerate(truths):
        observed = to_db(simulate(truth, grid.aspect_rad, grid.roll_rad, grid.freq_hz))
        mask = np.ones((4, 4), dtype=bool)
        mask[0, 0] = i % 2 == 0  # one record with a masked cell
        occ = occupancy_points(4000, i)
        records.append({"radar": torch.from_numpy(spec.normalise(observed, mask)), "radar_mask": torch.from_numpy(mask),
                        "eval_points": torch.from_numpy(sample_surface(truth, 1000, i)[0]),
                        "occ_points": torch.from_numpy(occ), "occ_inside": torch.from_numpy(contains(truth, occ)),
                        "index": torch.tensor(i), "observed": observed})

    class Known(ReconstructionModel):
        def __init__(self):
            super().__init__()
            self.layer = torch.nn.Linear(1, 1)

        def reconstruct(self, batch):
            return [Reconstruction(mesh=guesses[int(i)], predicted_iou=predicted[int(i)]) for i in batch["index"]]

        def test_step(self, batch, batch_idx):
            return None

    class Data(L.LightningDataModule):
        radar_spec = spec

        def test_dataloader(self):
            return DataLoader([{k: v for k, v in r.items() if k != "observed"} for r in records], batch_size=2)

    evaluator = ReconstructionEvaluator([ShapeScorer(1000, seed=0), ConsistencyScorer()], num_saved=0,
                                        save_dir=str(tmp_path))
    trainer = L.Trainer(default_root_dir=tmp_path, logger=False, accelerator="cpu", devices=1, callbacks=[evaluator],
                        enable_progress_bar=False, enable_model_summary=False, enable_checkpointing=False)
    trainer.test(Known(), datamodule=Data())
    logged = {k: v.item() for k, v in trainer.callback_metrics.items()}
    # the same value as reconstruct prints for that mesh and input: the dB the DataModule normalised, its mask
    direct = [radar_consistency(g, r["observed"], r["radar_mask"].numpy(), spec) for g, r in zip(guesses, records)]
    assert direct[0] < 1e-3 < min(direct[1:])  # the true box explains its radar
    assert logged["test/radar_consistency_mean"] == pytest.approx(np.mean(direct), rel=1e-4, abs=1e-6)
    with open(tmp_path / "reconstructions" / "test" / "epoch_000" / "scores.csv") as handle:
        rows = list(csv.DictReader(handle))
    iou = [float(row["iou"]) for row in rows]
    assert [float(row["radar_consistency"]) for row in rows] == pytest.approx(direct, rel=1e-4, abs=1e-6)  # float32 radar
    assert logged["test/spearman_radar_consistency_iou"] == pytest.approx(spearmanr(direct, iou).statistic)
    assert [float(row["predicted_iou"]) for row in rows] == pytest.approx(predicted)
    assert logged["test/predicted_iou_mean"] == pytest.approx(np.mean(predicted))
    assert logged["test/spearman_predicted_iou_iou"] == pytest.approx(spearmanr(predicted, iou).statistic)
