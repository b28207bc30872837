"""torchmetrics classes that pool per-sample scores into mean +- std, overall and per class.

The scores themselves come from the scorers (``metrics.scorers``); these classes only aggregate,
so every model, the callback and the CLI share one definition of each metric. States are
class-indexed sums (sum, sum of squares, count) with ``dist_reduce_fx="sum"``: DDP ranks reduce
by adding them, which gives exactly the pooled mean and std.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torchmetrics import Metric

from radar2shape.metrics.functional import FSCORE_TAU, metric_names

Labels = torch.Tensor | Sequence[int] | None


class MeanStd(Metric):
    """Mean and population std (ddof 0) of per-sample values, overall and per class.

    ``update(values [B], labels [B] | None)``; ``nan`` values mean "not defined for this
    sample" (IoU of a point set) and are skipped. ``compute()`` returns a dict of tensors:
    ``mean``, ``std``, ``count`` (scalars) and ``class_mean``, ``class_std``, ``class_count``
    (``[num_classes]``); means and stds are ``nan`` where the count is 0.
    """

    full_state_update = False
    name = "value"

    def __init__(self, num_classes: int = 1, **kwargs):
        super().__init__(**kwargs)
        self.num_classes = int(num_classes)
        for state in ("total", "total_sq", "count"):
            self.add_state(state, default=torch.zeros(self.num_classes, dtype=torch.float64), dist_reduce_fx="sum")

    def update(self, values: torch.Tensor | Sequence[float], labels: Labels = None) -> None:
        values = torch.as_tensor(values, dtype=torch.float64, device=self.total.device).reshape(-1)
        if labels is None or self.num_classes == 1:
            labels = torch.zeros(len(values), dtype=torch.long, device=self.total.device)
        labels = torch.as_tensor(labels, device=self.total.device).reshape(-1).long()
        if len(labels) != len(values):
            raise ValueError(f"{len(values)} values but {len(labels)} labels")
        if len(labels) and (labels.min() < 0 or labels.max() >= self.num_classes):
            raise ValueError(f"labels must lie in [0, {self.num_classes}), got {labels.tolist()}")
        keep = ~torch.isnan(values)
        values, labels = values[keep].to(self.total.dtype), labels[keep]
        self.total.index_add_(0, labels, values)
        self.total_sq.index_add_(0, labels, values * values)
        self.count.index_add_(0, labels, torch.ones_like(values))

    def compute(self) -> dict[str, torch.Tensor]:
        return {
            **_mean_std(self.total.sum(), self.total_sq.sum(), self.count.sum()),
            **{f"class_{k}": v for k, v in _mean_std(self.total, self.total_sq, self.count).items()},
        }


def _mean_std(total: torch.Tensor, total_sq: torch.Tensor, count: torch.Tensor) -> dict[str, torch.Tensor]:
    safe = count.clamp(min=1)
    mean = torch.where(count > 0, total / safe, torch.nan)
    var = torch.where(count > 0, (total_sq / safe - mean**2).clamp(min=0), torch.nan)
    return {"mean": mean, "std": var.sqrt(), "count": count}


class ChamferDistance(MeanStd):
    """Chamfer-L2 x 10^3 (lower is better); see ``metrics.functional.chamfer_l2``."""

    higher_is_better = False
    name = metric_names()["chamfer"]


class VolumetricIoU(MeanStd):
    """Volumetric IoU on occupancy points in the padded unit cube (higher is better)."""

    higher_is_better = True
    name = metric_names()["iou"]


class FScore(MeanStd):
    """F-score at threshold ``tau`` (default 1 % of the unit cube's side; higher is better)."""

    higher_is_better = True

    def __init__(self, num_classes: int = 1, tau: float = FSCORE_TAU, **kwargs):
        super().__init__(num_classes, **kwargs)
        self.tau = float(tau)
        self.name = metric_names(self.tau)["fscore"]


def pool_scores(scores: Sequence[dict[str, float]], labels: Labels = None, num_classes: int = 1,
                names: Sequence[str] | None = None) -> dict[str, dict[str, torch.Tensor]]:
    """Per-sample score dicts -> ``{name: MeanStd.compute()}`` for each score name.

    Pools on this process only: callers gather the scores of all ranks first, so records that a
    distributed sampler repeats can be dropped before pooling.
    """
    names = list(names if names is not None else (scores[0] if scores else {}))
    out = {}
    for name in names:
        metric = MeanStd(num_classes, sync_on_compute=False)
        metric.update([s.get(name, math.nan) for s in scores], labels)  # absent: not defined for that sample
        out[name] = metric.compute()
    return out
