"""IoU-S, IoU-R and MATCH-S on hand-computed cases, their metric classes and the callback."""

import math

import lightning as L
import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from radar2shape.geometry.profile import profile_to_mesh, resample_profile
from radar2shape.metrics.rollsym import (
    ProfileMatch,
    RadarIoU,
    RollSymEvaluator,
    SectionIoU,
    half_section_mask,
    predicted_profile,
    profile_match_distance,
    radar_iou,
    section_iou,
)
from radar2shape.models.base import Reconstruction


def rectangle(radius, z0, z1):
    """Half section of a cylinder: r in [0, radius], z in [z0, z1] (flat caps)."""
    return np.array([[radius, z0], [radius, z1]])


def test_section_iou_of_two_rectangles():
    # Edges on multiples of the 1/256 cell, so the raster is exact.
    low, high = rectangle(0.25, -0.25, 0.25), rectangle(0.25, 0.0, 0.5)
    assert section_iou(low, high) == pytest.approx(1 / 3)  # overlap 0.25 x 0.25, union 0.25 x 0.75
    assert section_iou(low, rectangle(0.125, -0.25, 0.25)) == pytest.approx(0.5)
    assert section_iou(low, low) == 1.0
    assert section_iou(low, rectangle(0.25, 0.3, 0.5)) == 0.0


def test_half_section_raster_area_matches_polygon_area():
    cone = np.array([[0.5, -0.5], [0.0, 0.5]])  # triangle of area 0.25
    cell = 1 / 256
    assert half_section_mask(cone, cell).sum() * cell**2 == pytest.approx(0.25, abs=2 * cell)
    assert half_section_mask(cone, cell).shape == (288, 144)  # z rows over [-0.5625, 0.5625], r columns


def test_match_s_identical_shifted_and_resampled():
    profile = np.array([[0.0, -0.4], [0.3, -0.4], [0.2, 0.1], [0.35, 0.1], [0.0, 0.4]])
    assert profile_match_distance(profile, profile) == pytest.approx(0.0, abs=1e-12)
    assert profile_match_distance(profile + [0.0, 0.07], profile) == pytest.approx(0.07)
    # the same outline with extra points on its edges: arc-length matching does not see them
    assert profile_match_distance(resample_profile(profile, 16), profile) == pytest.approx(0.0, abs=1e-12)


def test_radar_iou_by_hand():
    pred = np.array([[0.0, -30.0], [-5.0, -25.0]])  # within 20 dB of its peak: left column
    target = np.array([[-3.0, 0.0], [-50.0, -10.0]])  # top row and bottom right
    assert radar_iou(pred, target, 20.0) == pytest.approx(1 / 4)
    assert radar_iou(pred + 17.0, target, 20.0) == pytest.approx(1 / 4)  # relative to each peak
    assert radar_iou(pred, target, 40.0) == pytest.approx(3 / 4)
    with pytest.raises(ValueError, match="shape"):
        radar_iou(pred, target[:1])


def test_metric_classes_pool_mean_std_and_score_invalid_predictions():
    target = rectangle(0.25, -0.25, 0.25)
    preds = [target, rectangle(0.25, 0.0, 0.5), np.array([[-0.1, 0.0], [0.2, 0.3]]), None]
    iou_s = SectionIoU()
    iou_s.update(preds, [target] * 4)
    result = iou_s.compute()
    values = np.array([1.0, 1 / 3, 0.0, 0.0])  # invalid (negative radius) and missing score 0
    assert result["mean"].item() == pytest.approx(values.mean())
    assert result["std"].item() == pytest.approx(values.std())
    match = ProfileMatch()
    match.update(torch.tensor(np.stack([target, target + [0, 0.1]])), np.stack([target, target]))
    match.update(preds[2:], [target, target])  # undefined for invalid predictions: skipped
    out = match.compute()
    assert out["count"].item() == 2 and out["mean"].item() == pytest.approx(0.05)


RADAR = {"aspect_rad": np.linspace(0.0, np.pi, 12), "freq_hz": np.linspace(2e9, 4e9, 6), "size_m": 1.0}


def test_radar_iou_metric_simulates_both_shapes():
    target = rectangle(0.25, -0.5, 0.5)
    metric = RadarIoU(RADAR)
    metric.update([target, np.array([[0.0, -0.5], [0.5, 0.5]]), None], [target] * 3)
    scores = metric.compute()
    assert scores["count"].item() == 3
    assert metric.score(target, target) == 1.0
    cone_score = metric.score(np.array([[0.0, -0.5], [0.5, 0.5]]), target)
    assert 0.0 <= cone_score < 0.9  # a cone's returns are not a cylinder's
    assert scores["mean"].item() == pytest.approx((1.0 + cone_score + 0.0) / 3)


def test_profile_is_cut_from_a_mesh_when_the_model_gives_none():
    profile = np.array([[0.3, -0.5], [0.3, 0.0], [0.1, 0.5]])
    recovered = predicted_profile(Reconstruction(mesh=profile_to_mesh(profile, 64)))
    assert section_iou(recovered, profile) > 0.99
    assert predicted_profile(Reconstruction()) is None


class PerfectModel(L.LightningModule):
    """Reconstructs the ground truth exactly (as a mesh only), to check the callback's plumbing."""

    def __init__(self):
        super().__init__()
        self.layer = torch.nn.Linear(1, 1)

    def test_step(self, batch, batch_idx):
        pass

    def reconstruct(self, batch):
        return [Reconstruction(mesh=profile_to_mesh(p, 64)) for p in batch["profile"].numpy()]


def test_callback_logs_all_three_metrics_per_split():
    profiles = torch.tensor(np.stack([resample_profile(rectangle(0.25, -0.5, 0.5), 8),
                                      resample_profile(np.array([[0.0, -0.5], [0.4, 0.5]]), 8)]), dtype=torch.float32)
    batches = DataLoader([{"profile": profiles, "label": torch.tensor([0, 1])}], batch_size=None)
    callback = RollSymEvaluator(radar=RADAR, class_names=["a", "b"])
    trainer = L.Trainer(callbacks=[callback], logger=False, enable_progress_bar=False, enable_model_summary=False)
    logged = trainer.test(PerfectModel(), dataloaders=batches, verbose=False)[0]
    assert logged["test/iou_s_mean"] > 0.99 and logged["test/match_s_mean"] < 2e-3
    assert logged["test/iou_r_mean"] > 0.9  # the mesh cut back to a profile, re-meshed: nearly the same radar
    assert "test/b/iou_s_std" in logged
    assert math.isclose(callback.results["test"]["iou_s"], logged["test/iou_s_mean"], rel_tol=1e-6)
