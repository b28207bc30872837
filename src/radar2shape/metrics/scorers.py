"""Scorers: what :class:`~radar2shape.metrics.ReconstructionEvaluator` computes per sample.

A scorer turns one batch's reconstructions into one dict of named scores per sample; the
evaluator asks the model for the reconstructions once and hands them to every scorer, then pools,
logs and writes the scores. A new family of metrics is one small class here, not a new callback.

- :class:`ShapeScorer`: Chamfer-L2, volumetric IoU and F-score (``metrics.scoring``; docs/metrics.md);
- :class:`ProfileScorer`: IoU-S, MATCH-S and IoU-R of roll-symmetric shapes (``metrics.rollsym``);
- :class:`ConsistencyScorer`: the radar consistency of each reconstruction (``metrics.consistency``),
  a confidence without ground truth; the evaluator logs its rank correlation with IoU.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch

from radar2shape.errors import UserInputError
from radar2shape.metrics.functional import FSCORE_TAU
from radar2shape.metrics.rollsym import (
    DEFAULT_CELL,
    DEFAULT_EXTENT,
    DEFAULT_LEVEL_DB,
    DEFAULT_MATCH_POINTS,
    is_valid_profile,
    as_profiles,
    predicted_profile,
    profile_match_distance,
    profile_radar_db,
    radar_iou,
    section_iou,
)
from radar2shape.metrics.scoring import score_reconstruction


def _numpy(value) -> np.ndarray:
    return value.detach().cpu().numpy() if isinstance(value, torch.Tensor) else np.asarray(value)


class Scorer:
    """One family of per-sample scores. Subclasses set ``required_keys`` and implement :meth:`score`."""

    required_keys: tuple[str, ...] = ()

    def setup(self, trainer, pl_module) -> None:
        """Read what the scores need from the run (e.g. the dataset's radar grid); default nothing."""

    def check(self, batch: dict) -> None:
        """Fail before the model samples when the batch lacks what this scorer reads."""
        missing = [key for key in self.required_keys if key not in batch]
        if missing:
            raise KeyError(f"{type(self).__name__} needs batch keys {list(self.required_keys)}; missing {missing}")

    def counts(self, batch: dict) -> dict[str, int]:
        """Sampling sizes behind this batch's scores (logged, so a report can state them); default none."""
        return {}

    def score(self, recs: Sequence, batch: dict, index: np.ndarray) -> list[dict[str, float]]:
        """One dict of scores per reconstruction (``recs`` may be the first samples of the batch only).

        ``index`` holds the samples' record indices, for seeds that do not depend on the batching.
        A ``nan`` score means "undefined for this sample" and is left out of the pooled statistics.
        """
        raise NotImplementedError


class ShapeScorer(Scorer):
    """Chamfer-L2 x 10^3, IoU and F-score at ``tau`` against ``eval_points`` / ``occ_points`` / ``occ_inside``.

    Args:
        num_points: surface samples per prediction for Chamfer / F-score; None: as many as the
            batch's ground-truth ``eval_points`` (the paper's protocol: the same N on both sides).
        tau: F-score threshold (normalised units; 0.01 = 1 % of the unit cube's side).
        seed: base seed of the prediction sampling, plus the record index (so a score does not
            depend on the batching or the number of processes).
    """

    required_keys = ("eval_points", "occ_points", "occ_inside")

    def __init__(self, num_points: int | None = None, tau: float = FSCORE_TAU, seed: int = 0):
        self.num_points = None if num_points is None else int(num_points)
        self.tau, self.seed = float(tau), int(seed)

    def counts(self, batch):
        """Truth's surface samples, samples per prediction (Chamfer, F-score) and occupancy points (IoU: all of them)."""
        truth = int(batch["eval_points"].shape[1])
        return {"num_eval_points": truth, "num_pred_points": self.num_points or truth,
                "num_occ_points": int(batch["occ_points"].shape[1])}

    def score(self, recs, batch, index):
        gt_points, occ_points, gt_inside = (_numpy(batch[key]) for key in self.required_keys)
        n_points = self.num_points or gt_points.shape[1]
        return [
            score_reconstruction(rec, gt_points[i], occ_points[i], gt_inside[i], n_points, self.tau,
                                 self.seed + int(index[i]))
            for i, rec in enumerate(recs)
        ]


def _radar_grid(trainer, pl_module) -> dict | None:
    """The radar grid IoU-R simulates on: the DataModule's radar spec, else the model's."""
    datamodule = getattr(trainer, "datamodule", None)
    for spec in (getattr(datamodule, "radar_spec", None), getattr(pl_module, "radar_spec", None)):
        if spec is not None:
            grid = spec.grid
            return {"aspect_rad": grid.aspect_rad, "freq_hz": grid.freq_hz, "size_m": grid.size_m}
    return None


class ProfileScorer(Scorer):
    """IoU-S, MATCH-S and IoU-R (docs/rollsym.md) of each prediction's profile against the batch's ``profile``.

    A prediction's profile is ``rec.profile`` or, for mesh-only models, the mesh's section
    (``rollsym.predicted_profile``). A missing or invalid prediction scores IoU 0 and MATCH-S
    ``nan`` (undefined, so not pooled).

    Args:
        radar: grid for IoU-R (``aspect_rad``, ``freq_hz``, ``size_m``); default the DataModule's
            radar spec, else the model's. ``radar_iou=False`` skips IoU-R (it
            simulates every prediction).
        level_db, cell, extent, match_points, segments: the metric definitions' parameters.
    """

    required_keys = ("profile",)

    def __init__(self, radar: dict | None = None, radar_iou: bool = True, level_db: float = DEFAULT_LEVEL_DB,
                 cell: float = DEFAULT_CELL, extent: float = DEFAULT_EXTENT,
                 match_points: int = DEFAULT_MATCH_POINTS, segments: int = 64):
        self.radar, self.radar_iou = radar, bool(radar_iou)
        self.level_db, self.cell, self.extent = float(level_db), float(cell), float(extent)
        self.match_points, self.segments = int(match_points), int(segments)
        self._grid = None if radar is None else self._checked_grid(radar)
        self._target_images: dict[bytes, np.ndarray] = {}  # ground truth simulated once per run

    @staticmethod
    def _checked_grid(radar) -> dict:
        missing = [key for key in ("aspect_rad", "freq_hz") if key not in radar]
        if missing:
            raise UserInputError(f"ProfileScorer radar: missing {missing}; expected aspect_rad, freq_hz (and size_m)")
        return {"aspect_rad": np.asarray(radar["aspect_rad"], dtype=np.float64),
                "freq_hz": np.asarray(radar["freq_hz"], dtype=np.float64),
                "size_m": float(radar.get("size_m", 1.0))}

    def setup(self, trainer, pl_module) -> None:
        if not self.radar_iou or self.radar is not None:
            return
        radar = _radar_grid(trainer, pl_module)
        if radar is None:
            raise UserInputError("ProfileScorer: IoU-R needs a radar grid; pass radar={aspect_rad, freq_hz, size_m}, "
                                 "use a DataModule with a radar spec, or set radar_iou: false")
        self._grid = self._checked_grid(radar)

    def radar_image(self, profile: np.ndarray) -> np.ndarray:
        """dB image ``[A, F]`` of a profile on this scorer's grid."""
        grid = self._grid
        return profile_radar_db(profile, grid["aspect_rad"], grid["freq_hz"], grid["size_m"], self.segments)

    def _radar_iou(self, pred: np.ndarray, target: np.ndarray) -> float:
        key = np.ascontiguousarray(target).tobytes()
        if key not in self._target_images:
            self._target_images[key] = self.radar_image(target)
        return radar_iou(self.radar_image(pred), self._target_images[key], self.level_db)

    def score(self, recs, batch, index):
        targets = as_profiles(batch["profile"])
        rows = []
        for rec, target in zip(recs, targets):
            pred = predicted_profile(rec)
            valid = is_valid_profile(pred)
            row = {
                "iou_s": section_iou(pred, target, self.cell, self.extent) if valid else 0.0,
                "match_s": profile_match_distance(pred, target, self.match_points) if valid else math.nan,
            }
            if self.radar_iou:
                row["iou_r"] = self._radar_iou(pred, target) if valid else 0.0
            rows.append(row)
        return rows


class ConsistencyScorer(Scorer):
    """``radar_consistency``: each reconstruction re-simulated with PO on the input's grid, residual in
    power over the observed cells after one gain (``metrics.consistency``; 0 explains the input, 1 not
    at all). It reads no ground truth, so it is the confidence a user gets from ``reconstruct``;
    logged per shape beside IoU, with their Spearman correlation. One PO simulation per shape
    (seconds each): add it to test runs, not to frequent validation.
    """

    required_keys = ("radar", "radar_mask")

    def setup(self, trainer, pl_module) -> None:
        spec = getattr(trainer.datamodule, "radar_spec", None) if trainer.datamodule is not None else None
        if spec is None or spec.roll_symmetric:
            raise UserInputError("ConsistencyScorer: needs a 3D radar DataModule (aspect x roll x frequency)")
        self.spec = spec

    def score(self, recs: Sequence, batch: dict, index: np.ndarray) -> list[dict[str, float]]:
        from radar2shape.metrics.consistency import radar_consistency

        radar, mask = _numpy(batch["radar"]), _numpy(batch["radar_mask"]).astype(bool)
        rows = []
        for i, rec in enumerate(recs):
            mesh = getattr(rec, "mesh", None)
            if mesh is None or len(mesh.faces) == 0:
                rows.append({"radar_consistency": math.nan})
                continue
            db = radar[i].astype(np.float64) * self.spec.db_std + self.spec.db_mean
            rows.append({"radar_consistency": radar_consistency(mesh, db, mask[i], self.spec)})
        return rows
