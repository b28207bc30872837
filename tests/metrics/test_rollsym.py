"""IoU-S, IoU-R and MATCH-S on hand-computed cases, the ProfileScorer and the evaluator running it."""

import math
from types import SimpleNamespace

import lightning as L
import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from radar2shape.errors import UserInputError
from radar2shape.geometry.profile import profile_to_mesh, resample_profile
from radar2shape.geometry.query import contains, sample_surface
from radar2shape.metrics import ProfileScorer, ReconstructionEvaluator, ShapeScorer, pool_scores
from radar2shape.metrics.functional import occupancy_points
from radar2shape.metrics.rollsym import (
    half_section_mask,
    predicted_profile,
    profile_match_distance,
    radar_iou,
    section_iou,
)
from radar2shape.models.base import Reconstruction
from radar2shape.radar import RadarGrid
from radar2shape.radar.spec import RadarSpec


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


def profile_scores(scorer, preds, targets):
    """The scorer's rows for predictions given as profiles (None: no reconstruction at all)."""
    recs = [Reconstruction(profile=p) for p in preds]
    return scorer.score(recs, {"profile": targets}, np.arange(len(recs)))


def test_profile_scorer_pools_mean_std_and_scores_invalid_predictions():
    target = rectangle(0.25, -0.25, 0.25)
    preds = [target, rectangle(0.25, 0.0, 0.5), np.array([[-0.1, 0.0], [0.2, 0.3]]), None]
    rows = profile_scores(ProfileScorer(radar_iou=False), preds, [target] * 4)
    assert all(row.keys() == {"iou_s", "match_s"} for row in rows)
    result = pool_scores(rows)["iou_s"]
    values = np.array([1.0, 1 / 3, 0.0, 0.0])  # invalid (negative radius) and missing score 0
    assert result["mean"].item() == pytest.approx(values.mean())
    assert result["std"].item() == pytest.approx(values.std())
    rows = profile_scores(ProfileScorer(radar_iou=False), [target, target + [0, 0.1]], torch.tensor(np.stack([target, target])))
    rows += profile_scores(ProfileScorer(radar_iou=False), preds[2:], [target, target])  # undefined for invalid: skipped
    out = pool_scores(rows)["match_s"]
    assert out["count"].item() == 2 and out["mean"].item() == pytest.approx(0.05)


RADAR = {"aspect_rad": np.linspace(0.0, np.pi, 12), "freq_hz": np.linspace(2e9, 4e9, 6), "size_m": 1.0}


def test_profile_scorer_simulates_both_shapes_for_iou_r():
    target = rectangle(0.25, -0.5, 0.5)
    cone = np.array([[0.0, -0.5], [0.5, 0.5]])
    scorer = ProfileScorer(radar=RADAR)
    rows = profile_scores(scorer, [target, cone, None], [target] * 3)
    scores = pool_scores(rows)["iou_r"]
    assert scores["count"].item() == 3
    assert rows[0]["iou_r"] == 1.0
    assert 0.0 <= rows[1]["iou_r"] < 0.9  # a cone's returns are not a cylinder's
    assert rows[2]["iou_r"] == 0.0
    assert scores["mean"].item() == pytest.approx((1.0 + rows[1]["iou_r"] + 0.0) / 3)
    assert len(scorer._target_images) == 1  # the ground truth is simulated once


def test_profile_scorer_takes_the_grid_from_the_datamodule_radar_spec():
    grid = RadarGrid(RADAR["aspect_rad"], np.zeros(1), RADAR["freq_hz"], 2.0)
    trainer = SimpleNamespace(datamodule=SimpleNamespace(radar_spec=RadarSpec(grid, -20.0, 5.0, roll_symmetric=True)))
    scorer = ProfileScorer()
    scorer.setup(trainer, SimpleNamespace(radar_spec=None))
    assert scorer._grid["size_m"] == 2.0 and np.array_equal(scorer._grid["freq_hz"], RADAR["freq_hz"])
    with pytest.raises(UserInputError, match="IoU-R needs a radar grid"):
        ProfileScorer().setup(SimpleNamespace(datamodule=None), SimpleNamespace(radar_spec=None))
    ProfileScorer(radar_iou=False).setup(SimpleNamespace(datamodule=None), None)  # nothing to simulate: fine


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
        self.calls = 0

    def test_step(self, batch, batch_idx):
        pass

    def reconstruct(self, batch):
        self.calls += 1
        return [Reconstruction(mesh=profile_to_mesh(p, 64)) for p in batch["profile"].numpy()]


def test_evaluator_logs_the_profile_metrics_per_split(tmp_path):
    profiles = torch.tensor(np.stack([resample_profile(rectangle(0.25, -0.5, 0.5), 8),
                                      resample_profile(np.array([[0.0, -0.5], [0.4, 0.5]]), 8)]), dtype=torch.float32)
    batches = DataLoader([{"profile": profiles, "label": torch.tensor([0, 1])}], batch_size=None)
    callback = ReconstructionEvaluator([ProfileScorer(radar=RADAR)], class_names=["a", "b"], num_saved=0)
    trainer = L.Trainer(callbacks=[callback], logger=False, enable_progress_bar=False, enable_model_summary=False,
                        default_root_dir=tmp_path)
    logged = trainer.test(PerfectModel(), dataloaders=batches, verbose=False)[0]
    assert logged["test/iou_s_mean"] > 0.99 and logged["test/match_s_mean"] < 2e-3
    assert logged["test/iou_r_mean"] > 0.9  # the mesh cut back to a profile, re-meshed: nearly the same radar
    assert "test/b/iou_s_std" in logged
    assert math.isclose(callback.results["test"]["iou_s"]["mean"], logged["test/iou_s_mean"], rel_tol=1e-6)


def test_shape_and_profile_scorers_share_one_reconstruction_per_batch(tmp_path):
    profiles = [resample_profile(rectangle(0.25, -0.5, 0.5), 8), resample_profile(np.array([[0.0, -0.5], [0.4, 0.5]]), 8)]
    records = []
    for i, profile in enumerate(profiles * 2):
        mesh, occ = profile_to_mesh(profile, 64), occupancy_points(2000, i)
        records.append({"profile": torch.tensor(profile, dtype=torch.float32), "index": torch.tensor(i),
                        "eval_points": torch.from_numpy(sample_surface(mesh, 1000, i)[0]),
                        "occ_points": torch.from_numpy(occ), "occ_inside": torch.from_numpy(contains(mesh, occ))})
    callback = ReconstructionEvaluator([ShapeScorer(), ProfileScorer(radar_iou=False)], num_saved=1)
    trainer = L.Trainer(callbacks=[callback], logger=False, enable_progress_bar=False, enable_model_summary=False,
                        default_root_dir=tmp_path)
    model = PerfectModel()
    logged = trainer.test(model, dataloaders=DataLoader(records, batch_size=2), verbose=False)[0]
    assert model.calls == 2  # two batches, one reconstruct each
    assert logged["test/iou_s_mean"] > 0.99 and logged["test/iou_mean"] > 0.95 and logged["test/chamfer_l2_x1e3_mean"] < 1.0
    assert "test/iou_r_mean" not in logged
    csv = (tmp_path / "reconstructions" / "test" / "epoch_000" / "scores.csv").read_text().splitlines()
    assert csv[0] == "index,label,chamfer_l2_x1e3,iou,fscore_1pct,iou_s,match_s" and len(csv) == 5
    assert sorted(p.name for p in (tmp_path / "reconstructions" / "test" / "epoch_000").glob("sample_*")) == [
        "sample_000000.obj", "sample_000000.png"]
