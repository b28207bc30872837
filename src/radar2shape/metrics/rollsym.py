"""Roll-symmetric metrics: IoU-S, IoU-R and MATCH-S (docs/design.md section 6; docs/rollsym.md).

The paper does not publish exact definitions, so these are ours, fixed here and tested on
hand-computed cases. All work on (r, z) profiles in normalised coordinates (unit cube, so r <= 0.5
and |z| <= 0.5 for the ground truth), closed onto the axis (``geometry.profile.canonical_profile``).

- **IoU-S** (shape): the half cross-section ``{(r, z): 0 <= r <= R(z)}`` of prediction and truth
  rasterised on one fixed grid of square cells of side ``cell`` (default 1/256) covering
  ``r in [0, extent]``, ``z in [-extent, extent]`` (default extent 0.5625: the unit cube plus
  1/16 margin, so a slightly oversized prediction is still scored); a cell belongs to a section
  when its centre lies inside the closed profile polygon. IoU = |P & T| / |P | T|. Higher is better.
- **IoU-R** (radar): both shapes revolved to meshes and simulated with the project's PO simulator
  on the dataset's aspect x frequency grid at the dataset's physical size (roll 0, which is every
  roll for a solid of revolution); each dB image ``[A, F]`` is thresholded at ``level_db``
  (default 20 dB) below its own peak and IoU is taken over the two sets of cells. It scores whether
  the prediction's strong returns (specular flashes, tip and edge returns) appear at the right
  aspects and frequencies, independently of absolute level. Higher is better.
- **MATCH-S** (matching): both profiles resampled to ``k`` points (default 256) equally spaced by
  arc length from the bottom axis point to the top axis point, point ``i`` matched with point
  ``i``; the mean Euclidean distance of the pairs, in normalised units (1 = the object's longest
  side). Lower is better.

A prediction that is missing or not a valid profile (``geometry.profile.validate_profile`` fails)
scores IoU 0; its MATCH-S is undefined, so it is ``nan`` and skipped (the metric's count drops).
"""

from __future__ import annotations

import math

import lightning as L
import numpy as np
import torch
from matplotlib.path import Path as PolygonPath

from radar2shape.errors import UserInputError
from radar2shape.geometry.normalise import scaled
from radar2shape.geometry.profile import canonical_profile, mesh_to_profile, profile_to_mesh, validate_profile
from radar2shape.metrics.aggregate import MeanStd
from radar2shape.radar import simulate, to_db

DEFAULT_CELL = 1.0 / 256
DEFAULT_EXTENT = 0.5625
DEFAULT_LEVEL_DB = 20.0
DEFAULT_MATCH_POINTS = 256


def half_section_mask(profile, cell: float = DEFAULT_CELL, extent: float = DEFAULT_EXTENT) -> np.ndarray:
    """Bool raster ``[n_z, n_r]`` of the half cross-section: True where a cell centre is inside.

    Rows run over ``z`` from ``-extent`` upwards, columns over ``r`` from 0 outwards.
    """
    polygon = PolygonPath(canonical_profile(profile))  # closed implicitly along the axis
    n_r = int(round(extent / cell))
    r = (np.arange(n_r) + 0.5) * cell
    z = -extent + (np.arange(2 * n_r) + 0.5) * cell
    rr, zz = np.meshgrid(r, z)
    inside = polygon.contains_points(np.column_stack([rr.ravel(), zz.ravel()]))
    return inside.reshape(rr.shape)


def mask_iou(a: np.ndarray, b: np.ndarray) -> float:
    """|a & b| / |a | b| of two bool arrays (1.0 when both are empty: nothing to disagree on)."""
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)


def section_iou(pred, target, cell: float = DEFAULT_CELL, extent: float = DEFAULT_EXTENT) -> float:
    """IoU-S of two profiles (see the module docstring)."""
    return mask_iou(half_section_mask(pred, cell, extent), half_section_mask(target, cell, extent))


def arc_length_resample(profile, k: int = DEFAULT_MATCH_POINTS) -> np.ndarray:
    """``k`` points ``[k, 2]`` equally spaced by arc length along the canonical profile, both ends included."""
    points = canonical_profile(profile)
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    targets = np.linspace(0.0, s[-1], k)
    return np.column_stack([np.interp(targets, s, points[:, 0]), np.interp(targets, s, points[:, 1])])


def profile_match_distance(pred, target, k: int = DEFAULT_MATCH_POINTS) -> float:
    """MATCH-S of two profiles: mean distance of index-matched arc-length samples."""
    return float(np.linalg.norm(arc_length_resample(pred, k) - arc_length_resample(target, k), axis=1).mean())


def radar_iou(pred_db: np.ndarray, target_db: np.ndarray, level_db: float = DEFAULT_LEVEL_DB) -> float:
    """IoU of the cells within ``level_db`` of each image's own peak (images in dB, same shape)."""
    pred_db, target_db = np.asarray(pred_db), np.asarray(target_db)
    if pred_db.shape != target_db.shape:
        raise ValueError(f"radar images differ in shape: {pred_db.shape} vs {target_db.shape}")
    return mask_iou(pred_db >= pred_db.max() - level_db, target_db >= target_db.max() - level_db)


def profile_radar_db(profile, aspect_rad, freq_hz, size_m: float = 1.0, segments: int = 64,
                     floor_db: float = -100.0) -> np.ndarray:
    """dB image ``[A, F]`` of a profile's solid of revolution at roll 0, simulated at ``size_m``.

    The same path as the dataset builder: normalised mesh scaled to its physical size, PO with
    shadowing; roll 0 stands for every roll of a solid of revolution.
    """
    mesh = scaled(profile_to_mesh(profile, segments), size_m)
    return to_db(simulate(mesh, aspect_rad, [0.0], freq_hz)[:, 0], floor_db)


# ---- torchmetrics classes --------------------------------------------------------------------
def _profiles(values) -> list[np.ndarray | None]:
    """A batch ``[B, P, 2]`` (tensor or array) or a list of ``[P_i, 2]`` arrays / None -> list."""
    if isinstance(values, torch.Tensor):
        values = values.detach().cpu().numpy()
    return [None if v is None else np.asarray(v, dtype=np.float64) for v in values]


def _is_valid(profile) -> bool:
    if profile is None:
        return False
    try:
        validate_profile(profile)
    except UserInputError:
        return False
    return True


class ProfileMetric(MeanStd):
    """Mean +- std of a per-sample profile score: ``update(pred_profiles, target_profiles, labels)``.

    A prediction that is ``None`` or not a valid profile gets ``invalid_score``; targets must be valid.
    """

    invalid_score = 0.0

    def score(self, pred: np.ndarray, target: np.ndarray) -> float:
        raise NotImplementedError

    def update(self, pred, target, labels=None) -> None:
        values = [
            self.score(p, t) if _is_valid(p) else self.invalid_score
            for p, t in zip(_profiles(pred), _profiles(target), strict=True)
        ]
        super().update(values, labels)


class SectionIoU(ProfileMetric):
    """IoU-S (higher is better) on a raster of cell ``cell`` over ``[0, extent] x [-extent, extent]``."""

    higher_is_better = True
    name = "iou_s"

    def __init__(self, num_classes: int = 1, cell: float = DEFAULT_CELL, extent: float = DEFAULT_EXTENT, **kwargs):
        super().__init__(num_classes, **kwargs)
        self.cell, self.extent = float(cell), float(extent)

    def score(self, pred, target) -> float:
        return section_iou(pred, target, self.cell, self.extent)


class ProfileMatch(ProfileMetric):
    """MATCH-S (lower is better) with ``k`` arc-length samples; invalid predictions are ``nan`` (skipped)."""

    higher_is_better = False
    invalid_score = math.nan
    name = "match_s"

    def __init__(self, num_classes: int = 1, k: int = DEFAULT_MATCH_POINTS, **kwargs):
        super().__init__(num_classes, **kwargs)
        self.k = int(k)

    def score(self, pred, target) -> float:
        return profile_match_distance(pred, target, self.k)


class RadarIoU(ProfileMetric):
    """IoU-R (higher is better): both profiles simulated on ``radar`` (``aspect_rad``, ``freq_hz``,
    ``size_m``, as in a dataset manifest), thresholded ``level_db`` below each peak.

    Ground-truth images are cached by profile, so later epochs simulate only the predictions.
    """

    higher_is_better = True
    name = "iou_r"

    def __init__(self, radar: dict, num_classes: int = 1, level_db: float = DEFAULT_LEVEL_DB, segments: int = 64,
                 **kwargs):
        super().__init__(num_classes, **kwargs)
        self.aspect_rad = np.asarray(radar["aspect_rad"], dtype=np.float64)
        self.freq_hz = np.asarray(radar["freq_hz"], dtype=np.float64)
        self.size_m = float(radar.get("size_m", 1.0))
        self.level_db, self.segments = float(level_db), int(segments)
        self._target_images: dict[bytes, np.ndarray] = {}

    def image(self, profile: np.ndarray) -> np.ndarray:
        return profile_radar_db(profile, self.aspect_rad, self.freq_hz, self.size_m, self.segments)

    def score(self, pred, target) -> float:
        key = np.ascontiguousarray(target).tobytes()
        if key not in self._target_images:
            self._target_images[key] = self.image(target)
        return radar_iou(self.image(pred), self._target_images[key], self.level_db)


# ---- the callback ----------------------------------------------------------------------------
def predicted_profile(rec) -> np.ndarray | None:
    """A reconstruction's profile: the model's own (``rec.profile``) or the mesh's section y = 0.

    The fallback lets any model with a mesh output (e.g. the full 3D Radar2Shape) be scored; a mesh
    that is not one solid of revolution about z gives ``None`` (scored as invalid).
    """
    profile = getattr(rec, "profile", None)
    if profile is not None:
        return np.asarray(profile, dtype=np.float64)
    mesh = getattr(rec, "mesh", None)
    if mesh is None or len(mesh.faces) == 0:
        return None
    try:
        return mesh_to_profile(mesh)
    except (UserInputError, ValueError, IndexError):
        return None


class RollSymEvaluator(L.Callback):
    """Logs ``{split}/{iou_s,iou_r,match_s}_{mean,std}`` (and per class) for roll-symmetric data.

    Uses the same ``pl_module.reconstruct(batch)`` as :class:`ReconstructionEvaluator`; the batch
    must hold ``profile``. Profile models cache their last reconstruction, so running both
    callbacks does not sample twice.

    Args:
        radar: grid for IoU-R (``aspect_rad``, ``freq_hz``, ``size_m``); default the datamodule's
            ``manifest["radar"]``. ``radar_iou=False`` skips IoU-R (it simulates every prediction).
        level_db, cell, extent, match_points, segments: the metric definitions' parameters.
        every_n_epochs, val_max_samples: keep validation cheap; test is always scored in full.
    """

    def __init__(self, radar: dict | None = None, radar_iou: bool = True, level_db: float = DEFAULT_LEVEL_DB,
                 cell: float = DEFAULT_CELL, extent: float = DEFAULT_EXTENT, match_points: int = DEFAULT_MATCH_POINTS,
                 segments: int = 64, every_n_epochs: int = 1, val_max_samples: int | None = 16,
                 class_names: list[str] | None = None):
        super().__init__()
        self.radar, self.radar_iou, self.level_db, self.segments = radar, radar_iou, level_db, segments
        self.cell, self.extent, self.match_points = cell, extent, match_points
        self.every_n_epochs, self.val_max_samples, self.class_names = max(1, every_n_epochs), val_max_samples, class_names
        self.results: dict[str, dict[str, float]] = {}

    def setup(self, trainer, pl_module, stage: str) -> None:
        datamodule = getattr(trainer, "datamodule", None)
        names = self.class_names or getattr(datamodule, "class_names", None)
        self._names = [str(n) for n in names] if names else []
        radar = self.radar or getattr(datamodule, "manifest", {}).get("radar")
        if self.radar_iou and radar is None:
            raise ValueError("RollSymEvaluator: IoU-R needs a radar grid (pass radar=... or use a ProfileDataModule)")
        self._metrics = {split: self._make_metrics(radar) for split in ("val", "test")}
        self._seen = {"val": 0, "test": 0}

    def _make_metrics(self, radar) -> dict[str, ProfileMetric]:
        n = max(1, len(self._names))
        metrics = [SectionIoU(n, self.cell, self.extent), ProfileMatch(n, self.match_points)]
        if self.radar_iou:
            metrics.append(RadarIoU(radar, n, self.level_db, self.segments))
        return {m.name: m for m in metrics}

    def _scoring_val(self, trainer) -> bool:
        return not trainer.sanity_checking and (trainer.current_epoch + 1) % self.every_n_epochs == 0

    def on_validation_epoch_start(self, trainer, pl_module) -> None:
        self._start("val")

    def on_test_epoch_start(self, trainer, pl_module) -> None:
        self._start("test")

    def _start(self, split: str) -> None:
        self._seen[split] = 0
        for metric in self._metrics[split].values():
            metric.reset()

    def on_validation_batch_end(self, trainer, pl_module, outputs, batch, batch_idx, dataloader_idx=0) -> None:
        if self._scoring_val(trainer):
            limit = None if self.val_max_samples is None else self.val_max_samples - self._seen["val"]
            if limit is None or limit > 0:
                self._evaluate(pl_module, batch, "val", limit)

    def on_test_batch_end(self, trainer, pl_module, outputs, batch, batch_idx, dataloader_idx=0) -> None:
        self._evaluate(pl_module, batch, "test", None)

    def _evaluate(self, pl_module, batch: dict, split: str, limit: int | None) -> None:
        if "profile" not in batch:
            raise KeyError("RollSymEvaluator needs the batch key 'profile' (a ProfileDataModule)")
        preds = [predicted_profile(rec) for rec in pl_module.reconstruct(batch)][:limit]
        targets = _profiles(batch["profile"])[: len(preds)]
        labels = batch["label"][: len(preds)] if self._names and "label" in batch else None
        for metric in self._metrics[split].values():
            metric.update(preds, targets, labels)
        self._seen[split] += len(preds)

    def on_validation_epoch_end(self, trainer, pl_module) -> None:
        if self._scoring_val(trainer):
            self._finish(pl_module, "val")

    def on_test_epoch_end(self, trainer, pl_module) -> None:
        self._finish(pl_module, "test")

    def _finish(self, pl_module, split: str) -> None:
        results = {}
        for name, metric in self._metrics[split].items():
            values = {k: v.cpu().numpy() for k, v in metric.compute().items()}
            keys = [(f"{split}/{name}", values["mean"], values["std"], values["count"])]
            keys += [(f"{split}/{c}/{name}", values["class_mean"][i], values["class_std"][i], values["class_count"][i])
                     for i, c in enumerate(self._names)]
            for key, mean, std, count in keys:
                if count > 0:
                    pl_module.log(f"{key}_mean", float(mean))
                    pl_module.log(f"{key}_std", float(std))
            results[name] = float(values["mean"])
        self.results[split] = results
