"""``radar2shape evaluate``: output formats, normalisation, point clouds and clear input errors."""

import json

import numpy as np
import pytest
import trimesh

from radar2shape.cli import main
from radar2shape.metrics.functional import CHAMFER_WORST

FAST = ["--points", "3000", "--occ-points", "20000"]


@pytest.fixture
def pair(tmp_path):
    gt, pred = tmp_path / "gt.obj", tmp_path / "pred.ply"
    trimesh.creation.icosphere(3, 0.4).export(gt)
    trimesh.creation.icosphere(3, 0.35).export(pred)
    return pred, gt


def evaluate(capsys, *args):
    code = main(["evaluate", *map(str, args), *FAST])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_is_one_line_with_the_three_metrics(pair, capsys):
    code, out, _ = evaluate(capsys, *pair, "--json")
    assert code == 0 and len(out.strip().splitlines()) == 1
    scores = json.loads(out)
    assert list(scores) == ["chamfer_l2_x1e3", "iou", "fscore_1pct"]
    assert scores["iou"] == pytest.approx((0.35 / 0.4) ** 3, abs=0.03)
    code, table, _ = evaluate(capsys, *pair)
    assert code == 0 and "chamfer_l2_x1e3" in table and "{" not in table


def test_normalise_maps_both_by_the_ground_truth(tmp_path, pair, capsys):
    pred, gt = pair
    big_gt, big_pred = tmp_path / "big_gt.stl", tmp_path / "big_pred.stl"
    trimesh.load(gt).apply_scale(3.0).apply_translation([5, 0, 0]).export(big_gt)
    trimesh.load(pred).apply_scale(3.0).apply_translation([5, 0, 0]).export(big_pred)
    plain = json.loads(evaluate(capsys, pred, gt, "--json", "--tau", "0.02")[1])
    normalised = json.loads(evaluate(capsys, big_pred, big_gt, "--json", "--normalise", "--tau", "0.02")[1])
    # the sphere of radius 0.4 normalises to radius 0.5: distances scale by 1.25, squared by 1.5625
    assert normalised["chamfer_l2_x1e3"] == pytest.approx(1.5625 * plain["chamfer_l2_x1e3"], rel=0.1)
    assert normalised["iou"] == pytest.approx(plain["iou"], abs=0.03)
    assert "fscore_2pct" in normalised


def test_point_cloud_prediction_has_null_iou(tmp_path, pair, capsys):
    _, gt = pair
    cloud = tmp_path / "cloud.npy"
    np.save(cloud, trimesh.creation.icosphere(3, 0.35).sample(2000))
    scores = json.loads(evaluate(capsys, cloud, gt, "--json")[1])
    assert scores["iou"] is None and scores["chamfer_l2_x1e3"] < 10


def test_empty_prediction_scores_the_worst(tmp_path, pair, capsys):
    _, gt = pair
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    scores = json.loads(evaluate(capsys, empty, gt, "--json")[1])
    assert scores == {"chamfer_l2_x1e3": pytest.approx(CHAMFER_WORST * 1e3), "iou": 0.0, "fscore_1pct": 0.0}


@pytest.mark.parametrize(
    "pred_name, gt_name, message",
    [
        ("missing.obj", "gt.obj", "no such file"),
        ("pred.txt", "gt.obj", "unsupported suffix"),
        ("bad.npy", "gt.obj", "shape [N, 3]"),
        ("pred.ply", "empty.obj", "empty.obj"),
    ],
)
def test_unreadable_input_is_a_one_line_error(tmp_path, pair, capsys, pred_name, gt_name, message):
    (tmp_path / "pred.txt").write_text("1 2 3")
    np.save(tmp_path / "bad.npy", np.zeros((4, 2)))
    (tmp_path / "empty.obj").write_text("")
    code, out, err = evaluate(capsys, tmp_path / pred_name, tmp_path / gt_name, "--json")
    assert code == 2 and out == "" and err.startswith("error: ") and message in err and len(err.strip().splitlines()) == 1
