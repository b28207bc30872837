"""LIST baseline: radar localisation, local features, primitive checkpoints, overfitting eight shapes."""

import math

import pytest
import torch
from baseline_data import RADAR_SHAPE, mean_scores, one_thread, shape_batch, train_steps, trainer_roundtrip

from baselines import LIST
from baselines.list_net import radar_coordinates

TINY = dict(num_freq=RADAR_SHAPE[-1], feature_dim=64, encoder_width=0.125, coarse_points=128, cloud_dim=32, local_dim=16,
            mlp_hidden=128, mlp_layers=3, mesh_resolution=32)


@pytest.fixture(scope="module")
def batch():
    with one_thread():  # for every test of the module
        yield shape_batch(n_surface=512, n_sdf=2048)


def test_query_direction_maps_to_the_radar_cell_looking_along_it():
    points = torch.tensor([[0.0, 0.0, 0.3], [0.0, 0.0, -0.3], [0.3, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, -0.3, 0.0]])
    grid = radar_coordinates(points)  # x: roll / pi - 1, y: aspect / (pi / 2) - 1
    torch.testing.assert_close(grid[:, 1], torch.tensor([-1.0, 1.0, 0.0, 0.0, 0.0]))  # aspect 0, pi, pi/2 ...
    torch.testing.assert_close(grid[2:, 0], torch.tensor([-1.0, -0.5, 0.5]))  # roll 0, pi/2, 3 pi/2
    assert torch.isfinite(radar_coordinates(torch.zeros(1, 3))).all()


def test_each_query_reads_the_feature_map_where_the_radar_looks_along_it(batch):
    """With offsets switched off, a query samples the cell of its own direction: on maps that hold
    their own (roll, aspect) coordinates, the local feature is the query's radar coordinate."""
    torch.manual_seed(0)
    model = LIST(**{**TINY, "offset_scale": 0.0}).eval()
    ctx = model.context(batch["radar"][:1], batch["radar_mask"][:1])
    a, r = 16, 32
    rows = (torch.arange(a) + 0.5) / a * 2 - 1  # pixel centres in grid_sample units (align_corners=False)
    cols = (torch.arange(r) + 0.5) / r * 2 - 1
    coordinates = torch.zeros(1, TINY["local_dim"], a, r)
    coordinates[0, 0] = cols[None].expand(a, -1)
    coordinates[0, 1] = rows[:, None].expand(-1, r)
    ctx.maps = [coordinates]
    queries = 0.3 * torch.nn.functional.normalize(torch.tensor([[[1.0, 0.2, 0.1], [-0.3, 0.5, -0.4], [0.1, -1.0, 0.6]]]), dim=-1)
    local = model.local_features(ctx, queries, model.query_context(ctx, queries))
    torch.testing.assert_close(local[0, :, :2], radar_coordinates(queries)[0], atol=1e-5, rtol=0)


def test_checkpoint_holds_primitive_hyperparameters(batch, tmp_path):
    torch.manual_seed(0)
    model = LIST(**TINY)
    loaded, one = trainer_roundtrip(model, batch, tmp_path)
    ctx, loaded_ctx = model.context(one["radar"], one["radar_mask"]), loaded.context(one["radar"], one["radar_mask"])
    torch.testing.assert_close(loaded.sdf(loaded_ctx, one["sdf_points"][:, :64]), model.sdf(ctx, one["sdf_points"][:, :64]))


def test_overfits_eight_shapes(batch):
    """Fast learning test: 100 full-batch steps on half the SDF samples (~30 s on one core).
    Calibration: Chamfer x10^3 ~3.6, IoU ~0.67, F@1% ~0.12 (marching cubes at 32^3)."""
    torch.manual_seed(0)
    model = LIST(**TINY)
    half = {**batch, "sdf_points": batch["sdf_points"][:, ::2], "sdf_values": batch["sdf_values"][:, ::2]}
    history = train_steps(model, half, 100)
    scores = mean_scores(model, batch)
    assert history[-1] < 0.2 * history[0]
    assert scores["chamfer_l2_x1e3"] < 5.0 and scores["iou"] > 0.6, scores
    assert not math.isnan(scores["fscore_1pct"])


@pytest.mark.slow
def test_overfits_eight_shapes_best(batch):
    """Its own best on the overfit set: 600 steps (budget ~4 minutes on one core). Measured:
    Chamfer x10^3 0.65, IoU 0.86, F@1% 0.28 at 32^3 marching cubes."""
    torch.manual_seed(0)
    model = LIST(**TINY)
    train_steps(model, batch, 600)
    scores = mean_scores(model, batch)
    assert scores["chamfer_l2_x1e3"] < 1.0 and scores["iou"] > 0.8, scores
