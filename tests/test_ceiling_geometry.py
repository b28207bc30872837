"""scripts/ceiling_geometry.py: thin share and exact-SDF scores against closed forms, one error line on bad input."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("ceiling_geometry", REPO / "scripts" / "ceiling_geometry.py")
ceiling_geometry = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ceiling_geometry)


def test_thin_share_of_a_box_is_its_shell_volume_over_its_volume():
    # a 0.8 x 0.4 x 0.2 box: the share of its volume within d of the surface is 1 - (a-2d)(b-2d)(c-2d)/abc
    extents, d = np.array([0.8, 0.4, 0.2]), 0.03
    box = trimesh.creation.box(extents)
    rng = np.random.default_rng(0)
    points = np.concatenate([rng.uniform(-extents / 2, extents / 2, (100_000, 3)), rng.uniform(0.45, 0.5, (1000, 3))])
    inside = np.arange(len(points)) < 100_000  # the outside points (a corner beyond the box) must not count
    expected = 1 - np.prod(extents - 2 * d) / np.prod(extents)  # 0.4496
    assert ceiling_geometry.thin_share(box, points, inside, d) == pytest.approx(expected, abs=0.005)
    assert np.isnan(ceiling_geometry.thin_share(box, points, np.zeros(len(points), bool), d))


def test_exact_sdf_of_a_box_meshed_at_64_scores_near_one_and_a_thin_plate_vanishes_at_coarse_grids():
    rng = np.random.default_rng(0)
    occ = rng.uniform(-0.55, 0.55, (40_000, 3)).astype(np.float16)

    def record(extents):
        box = trimesh.creation.box(extents)
        eval_points, _ = trimesh.sample.sample_surface(box, 5000, seed=0)
        inside = np.all(np.abs(occ.astype(np.float64)) < np.asarray(extents) / 2, axis=1)
        return box, {"eval_points": eval_points.astype(np.float32), "occ_points": occ, "occ_inside": inside}

    box, rec = record([0.9, 0.6, 0.5])
    assert ceiling_geometry.exact_sdf_scores(box, rec, 64)["iou"] > 0.95
    # a plate 0.006 thick (a third of a 64^3 cell) keeps little of its volume on that grid
    plate, rec = record([0.9, 0.9, 0.006])
    assert ceiling_geometry.exact_sdf_scores(plate, rec, 64)["iou"] < 0.6


def test_scores_without_a_ceiling_column_are_one_error_line(tmp_path, monkeypatch):
    data = tmp_path / "data"
    data.mkdir()
    (data / "manifest.json").write_text('{"format": 1, "classes": ["a"], "splits": {"test": ["x"]}, "labels": {"test": [0]}}')
    scores = tmp_path / "s.csv"
    scores.write_text("index,label,iou\n0,0,0.5\n")
    out = tmp_path / "g.md"
    monkeypatch.setattr(sys, "argv", ["ceiling_geometry.py", "--data", str(data), "--scores", str(scores), "--out", str(out)])
    with pytest.raises(SystemExit) as exc:
        ceiling_geometry.main()
    message = str(exc.value)
    assert message.startswith("error: ") and "\n" not in message and not out.exists()
