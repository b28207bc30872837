"""Metric classes: pooled mean/std overall and per class, NaN skipping, DDP-style state merging."""

import math

import numpy as np
import pytest
import torch

from radar2shape.metrics.aggregate import ChamferDistance, FScore, MeanStd, VolumetricIoU, pool_scores

pytestmark = pytest.mark.filterwarnings("ignore:The ``compute`` method")  # computing empty metrics is tested

VALUES = np.random.default_rng(0).gamma(2.0, 1.5, size=40)
LABELS = np.random.default_rng(1).integers(0, 3, size=40)


def test_mean_and_population_std_overall_and_per_class():
    metric = MeanStd(num_classes=3)
    metric.update(VALUES[:25], LABELS[:25])
    metric.update(torch.tensor(VALUES[25:]), torch.tensor(LABELS[25:]))
    out = metric.compute()
    assert out["mean"].item() == pytest.approx(VALUES.mean())
    assert out["std"].item() == pytest.approx(VALUES.std())  # ddof 0
    assert out["count"].item() == 40
    for c in range(3):
        assert out["class_mean"][c].item() == pytest.approx(VALUES[LABELS == c].mean())
        assert out["class_std"][c].item() == pytest.approx(VALUES[LABELS == c].std())


def test_states_summed_across_ranks_give_the_pooled_statistics():
    """What DDP does: every state is reduced with a sum."""
    ranks = [MeanStd(num_classes=3), MeanStd(num_classes=3)]
    ranks[0].update(VALUES[:13], LABELS[:13])
    ranks[1].update(VALUES[13:], LABELS[13:])
    merged = MeanStd(num_classes=3)
    for name in ("total", "total_sq", "count"):
        setattr(merged, name, sum(getattr(rank, name) for rank in ranks))
        assert merged._reductions[name] is not None  # registered with dist_reduce_fx="sum"
    pooled = MeanStd(num_classes=3)
    pooled.update(VALUES, LABELS)
    for key, value in merged.compute().items():
        assert torch.allclose(value, pooled.compute()[key])
    ranks[0].merge_state(ranks[1])  # torchmetrics' own merge uses the same reductions
    assert ranks[0].compute()["std"].item() == pytest.approx(VALUES.std())


def test_nan_values_are_skipped_and_empty_classes_are_nan():
    metric = VolumetricIoU(num_classes=2)
    metric.update([0.5, math.nan, 0.7], [0, 0, 0])
    out = metric.compute()
    assert out["count"].item() == 2 and out["mean"].item() == pytest.approx(0.6)
    assert out["class_count"][1].item() == 0 and math.isnan(out["class_mean"][1].item())
    assert math.isnan(VolumetricIoU().compute()["mean"].item())


def test_one_class_ignores_labels_and_bad_labels_raise():
    metric = ChamferDistance()
    metric.update([1.0, 3.0], [5, 7])
    assert metric.compute()["mean"].item() == 2.0
    with pytest.raises(ValueError, match="labels"):
        ChamferDistance(num_classes=2).update([1.0], [2])


def test_names_and_directions():
    assert ChamferDistance.name == "chamfer_l2_x1e3" and ChamferDistance.higher_is_better is False
    assert VolumetricIoU.name == "iou" and VolumetricIoU.higher_is_better is True
    assert FScore().name == "fscore_1pct" and FScore(tau=0.02).name == "fscore_2pct"


def test_pooling_score_dicts_gives_every_name_its_statistics():
    scores = [{"chamfer_l2_x1e3": 1.0, "iou": 0.5, "fscore_1pct": 0.2}, {"chamfer_l2_x1e3": 3.0, "iou": math.nan, "fscore_1pct": 0.4}]
    out = pool_scores(scores, [0, 1], num_classes=2)
    assert list(out) == ["chamfer_l2_x1e3", "iou", "fscore_1pct"]
    assert out["chamfer_l2_x1e3"]["mean"].item() == 2.0 and out["iou"]["count"].item() == 1
    assert out["fscore_1pct"]["class_mean"].tolist() == pytest.approx([0.2, 0.4])
    assert pool_scores([], names=["iou"])["iou"]["count"].item() == 0
