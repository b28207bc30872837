"""The one evaluation callback: any ReconstructionModel in, Chamfer / IoU / F-score out.

It asks ``pl_module.reconstruct(batch)`` for one :class:`Reconstruction` per sample, scores
each against the batch's ground truth (``eval_points``, ``occ_points``, ``occ_inside``) with
``metrics.scoring``, and at epoch end logs ``{split}/{metric}_mean`` and ``_std`` overall and
``{split}/{class}/{metric}_mean`` / ``_std`` per class. It also writes per-sample scores (CSV)
and the first few reconstructions (mesh .obj or points .ply + a PNG next to the ground truth)
under ``<log dir>/reconstructions/<split>/epoch_<E>/``. Validation is kept cheap by
``every_n_epochs`` and ``val_max_samples``; sanity-check batches are not scored.
"""

from __future__ import annotations

import csv
import warnings
from pathlib import Path

import lightning as L
import numpy as np
import torch
import trimesh

from radar2shape.metrics.aggregate import ReconstructionMetrics
from radar2shape.metrics.functional import FSCORE_TAU
from radar2shape.metrics.render import save_comparison
from radar2shape.metrics.scoring import prediction_surface, score_reconstruction

REQUIRED_KEYS = ("eval_points", "occ_points", "occ_inside")
SPLITS = ("val", "test")


def _numpy(value) -> np.ndarray:
    return value.detach().cpu().numpy() if isinstance(value, torch.Tensor) else np.asarray(value)


class ReconstructionEvaluator(L.Callback):
    """Score every model's reconstructions with the shared metrics (docs/metrics.md).

    Args:
        num_points: surface samples per prediction for Chamfer / F-score.
        tau: F-score threshold (normalised units; 0.01 = 1 % of the unit cube's side).
        every_n_epochs: score validation every n epochs (test is always scored).
        val_max_samples: samples scored per validation epoch and rank (None: all).
        num_saved: reconstructions saved per epoch as files and PNGs (rank 0 only).
        class_names: per-class names; default ``trainer.datamodule.class_names`` when present,
            else no per-class logging.
        seed: base seed of the prediction sampling (plus the record index: reproducible
            whatever the batching).
        save_dir: where files go; default the trainer's log dir.
    """

    def __init__(
        self,
        num_points: int = 30_000,
        tau: float = FSCORE_TAU,
        every_n_epochs: int = 1,
        val_max_samples: int | None = 32,
        num_saved: int = 4,
        class_names: list[str] | None = None,
        seed: int = 0,
        save_dir: str | None = None,
    ):
        super().__init__()
        self.num_points, self.tau, self.seed = int(num_points), float(tau), int(seed)
        self.every_n_epochs, self.val_max_samples = max(1, int(every_n_epochs)), val_max_samples
        self.num_saved, self.class_names, self.save_dir = int(num_saved), class_names, save_dir
        self.results: dict[str, dict[str, dict[str, float]]] = {}  # last computed, per split

    # -- Lightning hooks -------------------------------------------------------------------
    def setup(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        if not callable(getattr(pl_module, "reconstruct", None)):
            name = type(pl_module).__name__
            raise TypeError(f"ReconstructionEvaluator needs a ReconstructionModel; {name} has no reconstruct(batch)")
        names = self.class_names or getattr(getattr(trainer, "datamodule", None), "class_names", None)
        self._names = [str(n) for n in names] if names else []
        self._metrics = {s: ReconstructionMetrics(max(1, len(self._names)), self.tau) for s in SPLITS}
        self._seen = dict.fromkeys(SPLITS, 0)
        self._rows: dict[str, list[dict]] = {s: [] for s in SPLITS}

    def on_validation_epoch_start(self, trainer, pl_module) -> None:
        self._start_epoch(trainer, pl_module, "val")

    def on_test_epoch_start(self, trainer, pl_module) -> None:
        self._start_epoch(trainer, pl_module, "test")

    def on_validation_batch_end(self, trainer, pl_module, outputs, batch, batch_idx, dataloader_idx=0) -> None:
        if self._scoring_val(trainer):
            limit = None if self.val_max_samples is None else self.val_max_samples - self._seen["val"]
            if limit is None or limit > 0:
                self._evaluate(trainer, pl_module, batch, "val", limit)

    def on_test_batch_end(self, trainer, pl_module, outputs, batch, batch_idx, dataloader_idx=0) -> None:
        self._evaluate(trainer, pl_module, batch, "test", None)

    def on_validation_epoch_end(self, trainer, pl_module) -> None:
        if self._scoring_val(trainer):
            self._finish_epoch(trainer, pl_module, "val")

    def on_test_epoch_end(self, trainer, pl_module) -> None:
        self._finish_epoch(trainer, pl_module, "test")

    # -- work ------------------------------------------------------------------------------
    def _scoring_val(self, trainer: L.Trainer) -> bool:
        return not trainer.sanity_checking and (trainer.current_epoch + 1) % self.every_n_epochs == 0

    def _start_epoch(self, trainer, pl_module, split: str) -> None:
        self._seen[split] = 0
        self._rows[split] = []
        self._metrics[split].reset()
        # States sit on the module's device only under DDP, where NCCL needs them there (the
        # module is on its device by now, not yet at setup).
        self._metrics[split].to(pl_module.device if trainer.world_size > 1 else torch.device("cpu"))

    def _evaluate(self, trainer, pl_module, batch: dict, split: str, limit: int | None) -> None:
        missing = [key for key in REQUIRED_KEYS if key not in batch]
        if missing:
            raise KeyError(f"ReconstructionEvaluator needs batch keys {list(REQUIRED_KEYS)}; missing {missing}")
        gt_points, occ_points, gt_inside = (_numpy(batch[key]) for key in REQUIRED_KEYS)
        recs = list(pl_module.reconstruct(batch))
        if len(recs) != len(gt_points):
            name = type(pl_module).__name__
            raise ValueError(f"{name}.reconstruct returned {len(recs)} reconstructions for a batch of {len(gt_points)}")
        recs = recs[:limit]
        n = len(recs)
        labels = _numpy(batch["label"]).reshape(-1)[:n] if "label" in batch else np.zeros(n, dtype=np.int64)
        index = _numpy(batch["index"]).reshape(-1)[:n] if "index" in batch else self._seen[split] + np.arange(n)
        scores = [
            score_reconstruction(
                rec, gt_points[i], occ_points[i], gt_inside[i], self.num_points, self.tau, self._seed(index[i])
            )
            for i, rec in enumerate(recs)
        ]
        self._metrics[split].update(scores, labels if self._names else None)
        for i, score in enumerate(scores):
            self._rows[split].append({"index": int(index[i]), "label": int(labels[i]), **score})
            if trainer.is_global_zero and self._seen[split] + i < self.num_saved:
                self._save(trainer, split, recs[i], gt_points[i], int(index[i]), score)
        self._seen[split] += n

    def _seed(self, index: int) -> int:
        return self.seed + int(index)

    def _finish_epoch(self, trainer, pl_module, split: str) -> None:
        # Every rank computes (the DDP sync is collective), also one that scored nothing.
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="The ``compute`` method")
            computed = self._metrics[split].compute()
        results = {name: {k: v.cpu().numpy().tolist() for k, v in values.items()} for name, values in computed.items()}
        self.results[split] = results
        for name, values in results.items():
            self._log(pl_module, f"{split}/{name}", values["mean"], values["std"], values["count"])
            for c, class_name in enumerate(self._names):
                per_class = (values[f"class_{k}"][c] for k in ("mean", "std", "count"))
                self._log(pl_module, f"{split}/{class_name}/{name}", *per_class)
        self._write_rows(trainer, split)

    @staticmethod
    def _log(pl_module, key: str, mean: float, std: float, count: float) -> None:
        if count > 0:  # nothing scored (e.g. IoU of point-set models): leave it absent, not NaN
            pl_module.log(f"{key}_mean", float(mean), sync_dist=False)
            pl_module.log(f"{key}_std", float(std), sync_dist=False)

    def _epoch_dir(self, trainer, split: str) -> Path:
        root = Path(self.save_dir or trainer.log_dir or trainer.default_root_dir)
        return root / "reconstructions" / split / f"epoch_{trainer.current_epoch:03d}"

    def _write_rows(self, trainer, split: str) -> None:
        rows = self._rows[split]
        if not rows:
            return
        suffix = f"_rank{trainer.global_rank}" if trainer.world_size > 1 else ""
        path = self._epoch_dir(trainer, split) / f"scores{suffix}.csv"
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)

    def _save(self, trainer, split: str, rec, gt_points: np.ndarray, index: int, score: dict) -> None:
        directory = self._epoch_dir(trainer, split)
        directory.mkdir(parents=True, exist_ok=True)
        stem = directory / f"sample_{index:06d}"
        pred_points = prediction_surface(rec, self.num_points, self._seed(index))
        if rec is not None and rec.mesh is not None and len(pred_points):
            rec.mesh.export(stem.with_suffix(".obj"))
        elif rec is not None and rec.mesh is None and len(pred_points):
            trimesh.PointCloud(pred_points).export(stem.with_suffix(".ply"))
        title = "  ".join(f"{k} {v:.4g}" for k, v in score.items())
        save_comparison(stem.with_suffix(".png"), pred_points, gt_points, title=f"#{index}  {title}")
