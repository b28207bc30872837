"""ReconstructionEvaluator in a real (tiny) Trainer, and the same numbers from the CLI.

A dummy ReconstructionModel returns known shapes per record, so every logged number is
checked against ``score_reconstruction`` and its closed form (tests/metrics/test_functional.py).
"""

import json
import math

import lightning as L
import numpy as np
import pytest
import torch
import trimesh
from torch.utils.data import DataLoader

from radar2shape.cli import main as cli_main
from radar2shape.commands.evaluate import load_prediction
from radar2shape.geometry.mesh_io import load_mesh
from radar2shape.geometry.query import contains, sample_surface
from radar2shape.metrics import ChamferDistance, FScore, ReconstructionEvaluator, ShapeScorer, VolumetricIoU
from radar2shape.metrics.functional import CHAMFER_WORST, occupancy_points
from radar2shape.metrics.scoring import score_reconstruction
from radar2shape.models.base import Reconstruction, ReconstructionModel

N_POINTS, N_OCC = 4000, 20_000
GT = trimesh.creation.icosphere(subdivisions=3, radius=0.4)
PREDICTIONS = [  # by record index; labels alternate 0, 1
    Reconstruction(mesh=trimesh.creation.icosphere(subdivisions=3, radius=0.35)),
    Reconstruction(),  # nothing: worst values
    Reconstruction(points=sample_surface(GT, 3000, seed=9)[0]),  # point set: no IoU
    Reconstruction(mesh=GT.copy()),
    Reconstruction(mesh=trimesh.creation.icosphere(subdivisions=3, radius=0.3)),
]


def record(index, gt=GT, seed=None, cover=None):
    seed = 100 + index if seed is None else seed
    occ = occupancy_points(N_OCC, seed + 1, cover)
    return {
        "eval_points": torch.from_numpy(sample_surface(gt, N_POINTS, seed)[0]),
        "occ_points": torch.from_numpy(occ),
        "occ_inside": torch.from_numpy(contains(gt, occ)),
        "label": torch.tensor(index % 2),
        "index": torch.tensor(index),
    }


class Known(ReconstructionModel):
    def __init__(self, predictions):
        super().__init__()
        self.predictions = predictions
        self.layer = torch.nn.Linear(1, 1)  # Lightning wants parameters

    def reconstruct(self, batch):
        return [self.predictions[int(i)] for i in batch["index"]]

    def validation_step(self, batch, batch_idx):
        return None

    def test_step(self, batch, batch_idx):
        return None


class Data(L.LightningDataModule):
    class_names = ["round", "other"]

    def __init__(self, records):
        super().__init__()
        self.records = records

    def val_dataloader(self):
        return DataLoader(self.records, batch_size=2)

    test_dataloader = val_dataloader


def run(tmp_path, records, predictions, stage="test", **options):
    evaluator = ReconstructionEvaluator([ShapeScorer(N_POINTS, seed=0)], num_saved=2, **options)
    trainer = L.Trainer(
        default_root_dir=tmp_path, logger=False, accelerator="cpu", devices=1, callbacks=[evaluator],
        enable_progress_bar=False, enable_model_summary=False, enable_checkpointing=False,
    )
    getattr(trainer, stage)(Known(predictions), datamodule=Data(records))
    return trainer, evaluator


@pytest.fixture(scope="module")
def records():
    return [record(i) for i in range(len(PREDICTIONS))]


def direct_scores(records):
    return [
        score_reconstruction(PREDICTIONS[i], r["eval_points"].numpy(), r["occ_points"].numpy(), r["occ_inside"].numpy(), N_POINTS, seed=i)
        for i, r in enumerate(records)
    ]


def test_test_loop_logs_the_shared_scores_overall_and_per_class(tmp_path, records):
    trainer, evaluator = run(tmp_path, records, PREDICTIONS)
    logged = {k: v.item() for k, v in trainer.callback_metrics.items()}
    scores = direct_scores(records)
    for name in ("chamfer_l2_x1e3", "iou", "fscore_1pct"):
        values = np.array([s[name] for s in scores])
        labels = np.arange(len(values)) % 2
        ok = ~np.isnan(values)
        assert logged[f"test/{name}_mean"] == pytest.approx(values[ok].mean())
        assert logged[f"test/{name}_std"] == pytest.approx(values[ok].std())
        for c, class_name in enumerate(Data.class_names):
            assert logged[f"test/{class_name}/{name}_mean"] == pytest.approx(values[ok & (labels == c)].mean())
    # the known shapes: worst values for the empty prediction, undefined IoU for the point set
    assert scores[1] == {"chamfer_l2_x1e3": CHAMFER_WORST * 1e3, "iou": 0.0, "fscore_1pct": 0.0}
    assert math.isnan(scores[2]["iou"]) and evaluator.results["test"]["iou"]["count"] == 4
    assert scores[0]["iou"] == pytest.approx((0.35 / 0.4) ** 3, abs=0.03)
    assert scores[3]["iou"] == 1.0
    # files: two reconstructions (a mesh and the empty one: picture only) and the per-sample CSV
    folder = tmp_path / "reconstructions" / "test" / "epoch_000"
    assert (folder / "sample_000000.obj").is_file() and (folder / "sample_000000.png").is_file()
    assert (folder / "sample_000001.png").is_file() and not (folder / "sample_000001.obj").exists()
    assert not (folder / "sample_000002.png").exists()
    assert len((folder / "scores.csv").read_text().splitlines()) == 1 + len(records)


def test_validation_respects_every_n_epochs_and_max_samples(tmp_path, records):
    trainer, evaluator = run(tmp_path, records, PREDICTIONS, stage="validate", every_n_epochs=1, val_max_samples=3)
    assert evaluator.results["val"]["chamfer_l2_x1e3"]["count"] == 3
    assert "val/chamfer_l2_x1e3_mean" in trainer.callback_metrics
    trainer, evaluator = run(tmp_path, records, PREDICTIONS, stage="validate", every_n_epochs=2)
    assert "val" not in evaluator.results and "val/chamfer_l2_x1e3_mean" not in trainer.callback_metrics


def test_a_model_without_reconstruct_is_rejected(tmp_path, records):
    class Plain(L.LightningModule):
        def test_step(self, batch, batch_idx):
            return None

    trainer = L.Trainer(default_root_dir=tmp_path, logger=False, callbacks=[ReconstructionEvaluator()], enable_progress_bar=False)
    with pytest.raises(TypeError, match="reconstruct"):
        trainer.test(Plain(), dataloaders=DataLoader(records, batch_size=2))


def test_cli_callback_and_metric_classes_agree_on_one_pair(tmp_path, capsys):
    pred_path, gt_path = tmp_path / "pred.obj", tmp_path / "gt.obj"
    trimesh.creation.icosphere(subdivisions=3, radius=0.33).apply_translation([0.02, 0, 0]).export(pred_path)
    GT.export(gt_path)
    seed = 5
    assert cli_main(["evaluate", str(pred_path), str(gt_path), "--points", str(N_POINTS), "--occ-points", str(N_OCC), "--seed", str(seed), "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)

    # the callback on a batch holding what the CLI samples (its seed layout: pred seed, truth seed + 1, occupancy seed + 2)
    gt, pred = load_mesh(gt_path), load_prediction(pred_path)
    occ = occupancy_points(N_OCC, seed + 2, [gt.bounds, pred.mesh.bounds])
    batch = {
        "eval_points": torch.from_numpy(sample_surface(gt, N_POINTS, seed + 1)[0]),
        "occ_points": torch.from_numpy(occ),
        "occ_inside": torch.from_numpy(contains(gt, occ)),
        "label": torch.tensor(0),
        "index": torch.tensor(0),
    }
    evaluator = ReconstructionEvaluator([ShapeScorer(N_POINTS, seed=seed)], num_saved=0)
    trainer = L.Trainer(default_root_dir=tmp_path, logger=False, callbacks=[evaluator], enable_progress_bar=False, enable_model_summary=False)
    trainer.test(Known([pred]), dataloaders=DataLoader([batch], batch_size=1))
    callback = {name: values["mean"] for name, values in evaluator.results["test"].items()}

    classes = {}
    for metric, key in ((ChamferDistance(), "chamfer_l2_x1e3"), (VolumetricIoU(), "iou"), (FScore(), "fscore_1pct")):
        metric.update([cli[key]])
        classes[key] = metric.compute()["mean"].item()
    assert cli.keys() == callback.keys() == classes.keys()
    for key in cli:
        assert cli[key] == pytest.approx(callback[key], rel=1e-9) and cli[key] == pytest.approx(classes[key], rel=1e-12)
    assert 0 < cli["iou"] < 1 and cli["chamfer_l2_x1e3"] > 2 * 0.05**2 * 1e3


class SlowKnown(Known):
    """Known shapes, and a training step that takes at least ``STEP_SLEEP`` seconds of wall time."""

    STEP_SLEEP = 0.05

    def training_step(self, batch, batch_idx):
        import time

        time.sleep(self.STEP_SLEEP)
        return self.layer(torch.ones(1, 1)).sum() * 0.0

    def configure_optimizers(self):
        return torch.optim.SGD(self.parameters(), lr=0.0)


class TrainData(Data):
    def train_dataloader(self):
        return DataLoader(list(range(3)), batch_size=1)  # three steps an epoch


def test_each_validation_logs_the_fits_wall_seconds_when_it_began(tmp_path, records):
    """``val/fit_seconds``: the learning curve against wall time; at least the sleeps of the steps before it."""
    evaluator = ReconstructionEvaluator([ShapeScorer(N_POINTS, seed=0)], every_n_epochs=1, num_saved=0)
    logger = L.pytorch.loggers.CSVLogger(tmp_path)
    trainer = L.Trainer(default_root_dir=tmp_path, logger=logger, accelerator="cpu", devices=1, max_epochs=2,
                        callbacks=[evaluator], num_sanity_val_steps=0, enable_progress_bar=False,
                        enable_model_summary=False, enable_checkpointing=False, log_every_n_steps=1)
    trainer.fit(SlowKnown(PREDICTIONS), datamodule=TrainData(records))
    import csv

    with open(tmp_path / "lightning_logs" / "version_0" / "metrics.csv", newline="") as handle:
        seconds = [float(r["val/fit_seconds"]) for r in csv.DictReader(handle) if r.get("val/fit_seconds")]
    assert len(seconds) == 2  # one per validation
    assert seconds[0] >= 3 * SlowKnown.STEP_SLEEP and seconds[1] >= seconds[0] + 3 * SlowKnown.STEP_SLEEP
