"""Shared metrics (docs/design.md section 6; docs/metrics.md): one definition for every model.

- ``functional``: per-sample Chamfer-L2, F-score and IoU on point sets and occupancy labels;
- ``scoring``: a model's ``Reconstruction`` -> those scores (sampling, containment, worst values);
- ``aggregate``: torchmetrics classes pooling scores into mean +- std, overall and per class;
- ``callback``: ``ReconstructionEvaluator``, the Lightning callback every experiment uses;
- ``rollsym``: IoU-S, IoU-R and MATCH-S for roll-symmetric shapes.
"""

from radar2shape.metrics.aggregate import ChamferDistance, FScore, MeanStd, ReconstructionMetrics, VolumetricIoU
from radar2shape.metrics.callback import ReconstructionEvaluator
from radar2shape.metrics.functional import CHAMFER_SCALE, CHAMFER_WORST, FSCORE_TAU, chamfer_l2, fscore, iou
from radar2shape.metrics.scoring import score_reconstruction

__all__ = [
    "CHAMFER_SCALE",
    "CHAMFER_WORST",
    "FSCORE_TAU",
    "ChamferDistance",
    "FScore",
    "MeanStd",
    "ReconstructionEvaluator",
    "ReconstructionMetrics",
    "VolumetricIoU",
    "chamfer_l2",
    "fscore",
    "iou",
    "score_reconstruction",
]
