"""Shared metrics (docs/design.md section 6; docs/metrics.md): one definition for every model.

- ``functional``: per-sample Chamfer-L2, F-score and IoU on point sets and occupancy labels;
- ``scoring``: a model's ``Reconstruction`` -> those scores (sampling, containment, worst values);
- ``rollsym``: IoU-S, IoU-R and MATCH-S for roll-symmetric shapes;
- ``scorers``: the per-sample score families the evaluator runs (``ShapeScorer``, ``ProfileScorer``,
  ``ConsistencyScorer``);
- ``aggregate``: torchmetrics classes pooling scores into mean +- std, overall and per class;
- ``callback``: ``ReconstructionEvaluator``, the Lightning callback every experiment uses.
"""

import importlib

# Names resolve on first use, so ``radar2shape evaluate`` (functional + scoring) never imports
# torchmetrics or Lightning, which the aggregate classes and the callback need.
_HOMES = {
    "ChamferDistance": "aggregate", "FScore": "aggregate", "MeanStd": "aggregate", "VolumetricIoU": "aggregate",
    "pool_scores": "aggregate", "ReconstructionEvaluator": "callback", "CHAMFER_SCALE": "functional",
    "CHAMFER_WORST": "functional", "FSCORE_TAU": "functional", "chamfer_l2": "functional", "fscore": "functional",
    "iou": "functional", "ConsistencyScorer": "scorers", "ProfileScorer": "scorers", "Scorer": "scorers", "ShapeScorer": "scorers",
    "score_reconstruction": "scoring",
}


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_HOMES[name]}"), name)
    globals()[name] = value
    return value


__all__ = [
    "CHAMFER_SCALE",
    "CHAMFER_WORST",
    "FSCORE_TAU",
    "ChamferDistance",
    "ConsistencyScorer",
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
