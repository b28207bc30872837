"""Chamfer-L2, F-score and IoU against closed forms, and the worst values of broken predictions.

Sampling error is bounded analytically: for N points sampled on a surface of area A, the
nearest sample to a point at height h over the surface is at squared distance h^2 + rho^2 with
rho^2 ~ Exp(mean A / (pi N)) (planar Poisson approximation, curvature radius >> sample gap).
Hence E[Chamfer] = 2 h^2 + (A1 + A2) / (pi N) and E[precision] = 1 - exp(-pi N (tau^2 - h^2) / A).
"""

import math

import numpy as np
import pytest
import trimesh

from radar2shape.geometry.query import contains, sample_surface
from radar2shape.metrics.functional import (
    CHAMFER_SCALE,
    CHAMFER_WORST,
    chamfer_l2,
    fscore,
    iou,
    metric_names,
    occupancy_points,
)
from radar2shape.metrics.scoring import score_reconstruction
from radar2shape.models.base import Reconstruction

N = 8_000
NAMES = metric_names()
R1 = 0.4


def ball(radius):
    return trimesh.creation.icosphere(subdivisions=4, radius=radius)


def expected_chamfer(h, area_1, area_2, n=N):
    return 2 * h * h + (area_1 + area_2) / (math.pi * n)


def expected_fscore(h, area_1, area_2, tau, n=N):
    gap = max(tau * tau - h * h, 0.0)
    precision, recall = 1 - math.exp(-math.pi * n * gap / area_2), 1 - math.exp(-math.pi * n * gap / area_1)
    return 0.0 if gap == 0 else 2 * precision * recall / (precision + recall)


@pytest.fixture(scope="module")
def occupancy():
    points = occupancy_points(60_000, seed=7)
    return points, ball(R1)


def score(pred_mesh, gt_mesh, occ_points, n=N, seed=0):
    gt_points, _ = sample_surface(gt_mesh, n, seed + 1)
    rec = pred_mesh if isinstance(pred_mesh, Reconstruction) else Reconstruction(mesh=pred_mesh)
    return score_reconstruction(rec, gt_points, occ_points, contains(gt_mesh, occ_points), n, seed=seed)


@pytest.mark.parametrize("r2", [0.35, 0.395, R1])
def test_concentric_spheres_match_closed_forms(r2, occupancy):
    occ_points, gt = occupancy
    pred = ball(r2)
    scores = score(pred, gt, occ_points)
    h = R1 - r2
    chamfer = expected_chamfer(h, gt.area, pred.area) * CHAMFER_SCALE
    # per-sample std of the two means is ~ mean / sqrt(N): 5 % is > 4 sigma at N = 8000
    assert scores[NAMES["chamfer"]] == pytest.approx(chamfer, rel=0.05)
    # icospheres of one subdivision are similar solids: volume ratio exactly (r2/r1)^3
    inside = (r2 / R1) ** 3
    sigma = math.sqrt(inside * (1 - inside) / (len(occ_points) * gt.volume / 1.1**3))
    assert scores[NAMES["iou"]] == pytest.approx(inside, abs=4 * sigma + 1e-12)
    assert scores[NAMES["fscore"]] == pytest.approx(expected_fscore(h, gt.area, pred.area, 0.01), abs=0.02)


def test_fscore_is_one_within_tau_and_zero_far_beyond():
    gt, near, far = ball(R1), ball(R1 - 0.002), ball(R1 - 0.1)
    points = {m: sample_surface(m, 10_000, i)[0] for i, m in enumerate((gt, near, far))}
    # tau = 3 cm: P(gap > tau) = exp(-pi N tau^2 / A) ~ 1e-6 per point at N = 10k, A = 2
    assert fscore(points[near], points[gt], tau=0.03) == 1.0
    assert fscore(points[far], points[gt], tau=0.01) == 0.0
    assert chamfer_l2(points[far], points[gt]) >= 2 * 0.1**2 * 0.99


@pytest.mark.parametrize("d", [0.1, 0.3])
def test_shifted_unit_cube_iou(d):
    cube = trimesh.creation.box(extents=(1, 1, 1))
    shifted = cube.copy().apply_translation([d, 0, 0])
    # points must cover both cubes: the padded unit cube grown to hold the shifted one
    points = occupancy_points(60_000, seed=1, cover=[cube.bounds, shifted.bounds])
    value = iou(contains(shifted, points), contains(cube, points))
    expected = (1 - d) / (1 + d)
    sigma = math.sqrt(expected * (1 - expected) / (60_000 * (1 + d) / (1.1 + d) / 1.1**2))
    assert value == pytest.approx(expected, abs=4 * sigma)


def test_identical_meshes(occupancy):
    occ_points, gt = occupancy
    scores = score(gt, gt, occ_points)
    assert scores[NAMES["iou"]] == 1.0
    assert scores[NAMES["chamfer"]] == pytest.approx(expected_chamfer(0, gt.area, gt.area) * CHAMFER_SCALE, rel=0.05)
    assert scores[NAMES["fscore"]] == pytest.approx(expected_fscore(0, gt.area, gt.area, 0.01), abs=0.02)


def test_open_prediction_scores_like_the_closed_one(occupancy):
    occ_points, gt = occupancy
    pred = ball(0.38)
    holed = pred.copy()
    keep = np.ones(len(holed.faces), bool)
    keep[np.random.default_rng(2).choice(len(keep), 60, replace=False)] = False
    holed.update_faces(keep)
    closed, opened = score(pred, gt, occ_points), score(holed, gt, occ_points)
    assert opened[NAMES["iou"]] == pytest.approx(closed[NAMES["iou"]], abs=0.01)
    assert opened[NAMES["chamfer"]] == pytest.approx(closed[NAMES["chamfer"]], rel=0.1)


def nan_mesh():
    mesh = ball(0.3)
    mesh.vertices[3] = np.nan
    return mesh


@pytest.mark.parametrize(
    "rec",
    [
        None,
        Reconstruction(),
        Reconstruction(mesh=trimesh.Trimesh()),
        Reconstruction(mesh=nan_mesh()),
        Reconstruction(mesh=trimesh.Trimesh([[0, 0, 0], [1, 1, 1], [2, 2, 2]], [[0, 1, 2]])),  # zero area
        Reconstruction(points=np.zeros((0, 3))),
    ],
    ids=["none", "nothing", "no-faces", "nan", "zero-area", "no-points"],
)
def test_empty_or_broken_predictions_score_the_worst(rec, occupancy):
    occ_points, gt = occupancy
    scores = score(rec, gt, occ_points, n=2000)
    assert scores == {NAMES["chamfer"]: CHAMFER_WORST * CHAMFER_SCALE, NAMES["iou"]: 0.0, NAMES["fscore"]: 0.0}


def test_point_set_prediction_has_no_iou(occupancy):
    occ_points, gt = occupancy
    points, _ = sample_surface(ball(0.35), N, seed=0)
    scores = score(Reconstruction(points=points), gt, occ_points)
    mesh_scores = score(ball(0.35), gt, occ_points)
    assert math.isnan(scores[NAMES["iou"]])
    assert scores[NAMES["chamfer"]] == pytest.approx(mesh_scores[NAMES["chamfer"]])  # same samples
    broken = score(Reconstruction(points=np.full((10, 3), np.nan)), gt, occ_points)
    assert broken[NAMES["chamfer"]] == CHAMFER_WORST * CHAMFER_SCALE and broken[NAMES["fscore"]] == 0.0


def test_worst_chamfer_bounds_any_pair_in_the_padded_cube():
    corners = np.array([[-0.55, -0.55, -0.55]]), np.array([[0.55, 0.55, 0.55]])
    assert chamfer_l2(*corners) == pytest.approx(CHAMFER_WORST)


def test_iou_edge_cases():
    assert iou([True, False], [False, True]) == 0.0
    assert iou([False, False], [False, False]) == 1.0
    assert iou([True, True, False], [True, False, False]) == 0.5
