"""Shared metrics (docs/design.md section 6; docs/metrics.md): one definition for every model.

- ``functional``: per-sample Chamfer-L2, F-score and IoU on point sets and occupancy labels;
- ``scoring``: a model's ``Reconstruction`` -> those scores (sampling, containment, worst values);
- ``rollsym``: IoU-S, IoU-R and MATCH-S for roll-symmetric shapes;
- ``scorers``: the per-sample score families the evaluator runs (``ShapeScorer``, ``ProfileScorer``);
- ``aggregate``: torchmetrics classes pooling scores into mean +- std, overall and per class;
- ``callback``: ``ReconstructionEvaluator``, the Lightning callback every experiment uses.
"""

from radar2shape.metrics.aggregate import ChamferDistance, FScore, MeanStd, VolumetricIoU, pool_scores
from radar2shape.metrics.callback import ReconstructionEvaluator
from radar2shape.metrics.functional import CHAMFER_SCALE, CHAMFER_WORST, FSCORE_TAU, chamfer_l2, fscore, iou
from radar2shape.metrics.scorers import ProfileScorer, Scorer, ShapeScorer
from radar2shape.metrics.scoring import score_reconstruction

__all__ = [
    "CHAMFER_SCALE",
    "CHAMFER_WORST",
    "FSCORE_TAU",
    "ChamferDistance",
    "FScore",
    "MeanStd",
    "ProfileScorer",
    "ReconstructionEvaluator",
    "Scorer",
    "ShapeScorer",
    "VolumetricIoU",
    "chamfer_l2",
    "fscore",
    "iou",
    "pool_scores",
    "score_reconstruction",
]
