"""The evaluator's diagnostics: radar dependence (a fixed derangement of the radars), the ceiling
hook, and the counts behind every mean, on stub models whose scores are known by hand.

Shapes are concentric cubes of half-side 0.2, 0.3, 0.4 scored on a regular occupancy grid
(coordinates at odd multiples of 0.025, so no point lies on a face): 8, 12 and 16 grid
coordinates per axis fall inside, so the IoU of cube a predicted for cube b is
(min(n_a, n_b) / max(n_a, n_b))^3 exactly.
"""

import math

import lightning as L
import numpy as np
import pytest
import torch
import trimesh
from torch.utils.data import DataLoader

from radar2shape.geometry.query import contains, sample_surface
from radar2shape.metrics import ProfileScorer, ReconstructionEvaluator, ShapeScorer
from radar2shape.metrics.callback import standard_error, take
from radar2shape.models.base import Reconstruction, ReconstructionModel

HALF = (0.2, 0.3, 0.4)
INSIDE = (8, 12, 16)  # grid coordinates per axis inside each cube
GRID = -0.525 + 0.05 * np.arange(22)
OCC = np.stack(np.meshgrid(GRID, GRID, GRID, indexing="ij"), -1).reshape(-1, 3).astype(np.float32)
CUBES = [trimesh.creation.box(extents=[2 * h] * 3) for h in HALF]
N_POINTS = 300


def records(n=len(CUBES)):
    out = []
    for i in range(n):
        cube = CUBES[i % len(CUBES)]
        out.append({
            "radar": torch.full((2, 3, 4), float(i)),  # the radar "names" its shape
            "radar_mask": torch.ones(2, 3, dtype=torch.bool),
            "eval_points": torch.from_numpy(sample_surface(cube, N_POINTS, 10 + i)[0]),
            "occ_points": torch.from_numpy(OCC),
            "occ_inside": torch.from_numpy(contains(cube, OCC)),
            "label": torch.tensor(0),
            "index": torch.tensor(i),
        })
    return out


class Stub(ReconstructionModel):
    """``lookup``: the true mesh of the shape whose radar it reads; else the shape of the record index."""

    def __init__(self, lookup=True, ceiling=None):
        super().__init__()
        self.lookup, self.ceiling = lookup, ceiling
        self.layer = torch.nn.Linear(1, 1)

    def reconstruct(self, batch):
        ids = batch["radar"][:, 0, 0, 0].long() if self.lookup else batch["index"]
        return [Reconstruction(mesh=CUBES[int(i) % len(CUBES)].copy()) for i in ids]

    def reconstruct_ceiling(self, batch):
        if self.ceiling is None:
            return None
        return [Reconstruction(mesh=self.ceiling.copy()) for _ in batch["index"]]

    def test_step(self, batch, batch_idx):
        return None

    validation_step = test_step


def run(tmp_path, model, data, batch_size, scorers=None, stage="test", **options):
    evaluator = ReconstructionEvaluator(scorers or [ShapeScorer(N_POINTS)], num_saved=0, **options)
    trainer = L.Trainer(default_root_dir=tmp_path, logger=False, accelerator="cpu", devices=1, callbacks=[evaluator],
                        enable_progress_bar=False, enable_model_summary=False, enable_checkpointing=False)
    getattr(trainer, stage)(model, dataloaders=DataLoader(data, batch_size=batch_size))
    return {k: v.item() for k, v in trainer.callback_metrics.items()}, evaluator


# Shape j is reconstructed from the radar of the shape before it (shape 0 from the last one).
SWAPPED_IOU = [(8 / 16) ** 3, (8 / 12) ** 3, (12 / 16) ** 3]
DEPENDENCE = 1.0 - np.array(SWAPPED_IOU)  # own radar: the true mesh, IoU 1


@pytest.mark.parametrize("batch_size", [1, 2, 3])
def test_lookup_model_dependence_is_the_hand_value_for_any_batch_size(tmp_path, batch_size):
    logged, evaluator = run(tmp_path, Stub(lookup=True), records(), batch_size)
    assert logged["test/iou_mean"] == 1.0
    assert logged["test/radar_dependence_iou_mean"] == pytest.approx(DEPENDENCE.mean(), abs=1e-6)  # float32 log
    assert evaluator.results["test"]["radar_dependence_iou"]["mean"] == pytest.approx(DEPENDENCE.mean(), abs=1e-12)
    assert logged["test/radar_dependence_iou_se"] == pytest.approx(DEPENDENCE.std(ddof=1) / math.sqrt(3), abs=1e-6)
    assert logged["test/radar_dependence_iou_count"] == 3 and logged["test/num_shapes"] == 3
    assert logged["test/radar_dependence_fscore_1pct_mean"] > 0  # wrong cubes are far from the truth's surface
    assert logged["test/radar_dependence_chamfer_l2_x1e3_mean"] < 0  # lower Chamfer from the own radar
    rows = sorted(evaluator._rows["test"], key=lambda r: r["index"])
    assert [r["radar_dependence_iou"] for r in rows] == pytest.approx(list(DEPENDENCE), abs=1e-12)
    scores = (tmp_path / "reconstructions" / "test" / "epoch_000" / "scores.csv").read_text().splitlines()
    assert "radar_dependence_iou" in scores[0] and len(scores) == 4


def test_model_that_ignores_the_radar_has_zero_dependence(tmp_path):
    logged, _ = run(tmp_path, Stub(lookup=False), records(), 2)
    for name in ("iou", "chamfer_l2_x1e3", "fscore_1pct"):
        assert logged[f"test/radar_dependence_{name}_mean"] == 0.0
        assert logged[f"test/radar_dependence_{name}_std"] == 0.0


def test_one_shape_has_no_partner_and_the_option_turns_it_off(tmp_path):
    logged, evaluator = run(tmp_path, Stub(), records(1), 1)
    assert "test/radar_dependence_iou_mean" not in logged and logged["test/iou_mean"] == 1.0
    logged, _ = run(tmp_path, Stub(), records(), 2, radar_dependence=False)
    assert not any("radar_dependence" in key for key in logged)
    # validation runs no diagnostics unless asked
    logged, _ = run(tmp_path, Stub(), records(), 2, stage="validate", val_max_samples=None)
    assert "val/iou_mean" in logged and "val/radar_dependence_iou_mean" not in logged
    logged, _ = run(tmp_path, Stub(), records(), 2, stage="validate", val_max_samples=2, diagnostics_on_val=True)
    # two shapes scored: 0 from 1's radar and 1 from 0's radar
    assert logged["val/radar_dependence_iou_mean"] == pytest.approx(1 - (8 / 12) ** 3, abs=1e-6)


def test_ceiling_hook_is_scored_and_optional(tmp_path):
    logged, _ = run(tmp_path, Stub(ceiling=CUBES[1]), records(), 2)
    ceiling = np.array([(8 / 12) ** 3, 1.0, (12 / 16) ** 3])  # cube 1 for every shape
    assert logged["test/ceiling_iou_mean"] == pytest.approx(ceiling.mean(), abs=1e-6)
    assert logged["test/ceiling_iou_count"] == 3
    logged, _ = run(tmp_path, Stub(ceiling=None), records(), 2)
    assert not any("ceiling" in key for key in logged)
    logged, _ = run(tmp_path, Stub(ceiling=CUBES[1]), records(), 2, ceiling=False)
    assert not any("ceiling" in key for key in logged)


def test_counts_of_points_and_shapes_are_logged(tmp_path):
    logged, evaluator = run(tmp_path, Stub(), records(), 2)
    assert logged["test/num_eval_points"] == N_POINTS and logged["test/num_pred_points"] == N_POINTS
    assert logged["test/num_occ_points"] == 22**3  # IoU on every occupancy point the batch holds
    assert evaluator.counts["test"]["num_shapes"] == 3 and logged["test/iou_count"] == 3


class ProfileStub(Stub):
    def reconstruct(self, batch):
        return [Reconstruction(profile=cylinder(int(i))) for i in batch["radar"][:, 0, 0].long()]


def cylinder(i):
    r = (8, 12, 16)[i] / 64  # cell edges of a 1/64 raster: the section holds 8, 12 or 16 columns
    return np.array([[0.0, -0.25], [r, -0.25], [r, 0.25], [0.0, 0.25]])


def test_profile_scorer_dependence(tmp_path):
    data = [{"radar": torch.full((3, 4), float(i)), "radar_mask": torch.ones(3, dtype=torch.bool),
             "profile": torch.from_numpy(cylinder(i)).float(), "label": torch.tensor(0), "index": torch.tensor(i)}
            for i in range(3)]
    logged, _ = run(tmp_path, ProfileStub(), data, 1, scorers=[ProfileScorer(radar_iou=False, cell=1 / 64)])
    dependence = 1 - np.array([8 / 16, 8 / 12, 12 / 16])  # IoU-S of nested rectangles: ratio of widths
    assert logged["test/iou_s_mean"] == 1.0
    assert logged["test/radar_dependence_iou_s_mean"] == pytest.approx(dependence.mean(), abs=1e-6)
    assert logged["test/radar_dependence_iou_s_se"] == pytest.approx(dependence.std(ddof=1) / math.sqrt(3), abs=1e-6)


def test_take_and_standard_error():
    batch = {"radar": torch.arange(6).reshape(3, 2), "names": ["a", "b", "c"], "scalar": torch.tensor(1.0)}
    part = take(batch, slice(1, 3))
    assert part["radar"].tolist() == [[2, 3], [4, 5]] and part["names"] == ["b", "c"] and part["scalar"] == 1.0
    values = np.array([1.0, 2.0, 4.0])
    assert standard_error(values.std(), 3) == pytest.approx(values.std(ddof=1) / math.sqrt(3))
    assert math.isnan(standard_error(0.0, 1))


class CountingStub(Stub):
    """A lookup stub that says it ignores the radar; counts its reconstructions."""

    reads_radar = False

    def __init__(self):
        super().__init__(lookup=True)
        self.calls = 0

    def reconstruct(self, batch):
        self.calls += len(batch["index"])
        return super().reconstruct(batch)


def test_a_model_that_declares_it_ignores_the_radar_is_reconstructed_once(tmp_path):
    """No swapped-radar pass for ``reads_radar = False`` (a Stage-1 autoencoder, the mean shape):
    even a stub whose output would change with the radar gets no dependence row."""
    model = CountingStub()
    logged, _ = run(tmp_path, model, records(), 2)
    assert model.calls == 3 and logged["test/iou_mean"] == 1.0
    assert not any("radar_dependence" in key for key in logged)
