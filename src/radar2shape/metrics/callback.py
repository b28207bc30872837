"""The one evaluation callback: any ReconstructionModel in, the scorers' metrics out.

Per batch it asks ``pl_module.reconstruct(batch)`` once and gives the reconstructions to every
scorer (``metrics.scorers``: shape metrics by default, roll-symmetric ones on request). At epoch
end the per-sample rows of all ranks are gathered (a record a distributed sampler repeats counts
once), pooled into ``{split}/{metric}_mean`` / ``_std`` overall and ``{split}/{class}/{metric}_...``
per class, and rank zero writes them (``scores.csv``) with the reconstructions of the first few
records (mesh .obj or points .ply + a PNG next to the ground truth) under
``<log dir>/reconstructions/<split>/epoch_<E>/``. So one process and N processes log and write
the same. Validation is kept cheap by ``every_n_epochs`` and ``val_max_samples``; sanity-check
batches are not scored.
"""

from __future__ import annotations

import csv
from pathlib import Path

import lightning as L
import numpy as np
import torch
import torch.distributed as dist
import trimesh

from radar2shape.metrics.aggregate import pool_scores
from radar2shape.metrics.render import save_comparison
from radar2shape.metrics.scorers import Scorer, ShapeScorer
from radar2shape.metrics.scoring import prediction_surface
from radar2shape.models.base import batch_size_of

SPLITS = ("val", "test")
PICTURE_POINTS = 30_000  # surface samples drawn per saved reconstruction's PNG


def _numpy(value) -> np.ndarray:
    return value.detach().cpu().numpy() if isinstance(value, torch.Tensor) else np.asarray(value)


def _all_gather(trainer: L.Trainer, value) -> list:
    """``value`` of every rank, in rank order (just ``[value]`` in one process)."""
    if trainer.world_size == 1 or not (dist.is_available() and dist.is_initialized()):
        return [value]
    out = [None] * dist.get_world_size()
    dist.all_gather_object(out, value)
    return out


class ReconstructionEvaluator(L.Callback):
    """Score every model's reconstructions with pluggable scorers (docs/metrics.md).

    Args:
        scorers: what to compute per sample; default ``[ShapeScorer()]`` (Chamfer, IoU, F-score).
            ``[ShapeScorer(), ProfileScorer()]`` adds IoU-S / MATCH-S / IoU-R from the same
            reconstructions.
        every_n_epochs: score validation every n epochs (test is always scored).
        val_max_samples: samples scored per validation epoch and rank (None: all).
        num_saved: reconstructions saved per epoch as files and PNGs: those of the lowest record
            indices, written by rank zero.
        class_names: per-class names; default ``trainer.datamodule.class_names`` when present,
            else no per-class logging.
        save_dir: where files go; default the trainer's log dir.

    Batches should carry ``index`` (record indices): it seeds the sampling, orders the rows and
    drops the records a distributed sampler repeats to even out the ranks.
    """

    def __init__(
        self,
        scorers: list[Scorer] | None = None,
        every_n_epochs: int = 1,
        val_max_samples: int | None = 32,
        num_saved: int = 4,
        class_names: list[str] | None = None,
        save_dir: str | None = None,
    ):
        super().__init__()
        self.scorers = list(scorers) if scorers else [ShapeScorer()]
        self.every_n_epochs, self.val_max_samples = max(1, int(every_n_epochs)), val_max_samples
        self.num_saved, self.class_names, self.save_dir = int(num_saved), class_names, save_dir
        self.results: dict[str, dict[str, dict]] = {}  # last computed, per split

    # -- Lightning hooks -------------------------------------------------------------------
    def setup(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        if not callable(getattr(pl_module, "reconstruct", None)):
            name = type(pl_module).__name__
            raise TypeError(f"ReconstructionEvaluator needs a ReconstructionModel; {name} has no reconstruct(batch)")
        names = self.class_names or getattr(getattr(trainer, "datamodule", None), "class_names", None)
        self._names = [str(n) for n in names] if names else []
        for scorer in self.scorers:
            scorer.setup(trainer, pl_module)
        self._seen = dict.fromkeys(SPLITS, 0)
        self._rows: dict[str, list[dict]] = {s: [] for s in SPLITS}
        self._saved: dict[str, list[tuple]] = {s: [] for s in SPLITS}  # (index, rec, gt points, row)

    def on_validation_epoch_start(self, trainer, pl_module) -> None:
        self._start_epoch("val")

    def on_test_epoch_start(self, trainer, pl_module) -> None:
        self._start_epoch("test")

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

    def _start_epoch(self, split: str) -> None:
        self._seen[split] = 0
        self._rows[split] = []
        self._saved[split] = []

    def _evaluate(self, trainer, pl_module, batch: dict, split: str, limit: int | None) -> None:
        for scorer in self.scorers:
            scorer.check(batch)
        size = batch_size_of(batch)
        recs = list(pl_module.reconstruct(batch))
        if len(recs) != size:
            name = type(pl_module).__name__
            raise ValueError(f"{name}.reconstruct returned {len(recs)} reconstructions for a batch of {size}")
        recs = recs[:limit]
        n = len(recs)
        labels = _numpy(batch["label"]).reshape(-1)[:n] if "label" in batch else np.zeros(n, dtype=np.int64)
        if "index" in batch:
            index = _numpy(batch["index"]).reshape(-1)[:n]
        else:  # the position in the split under an interleaving distributed sampler
            index = (self._seen[split] + np.arange(n)) * trainer.world_size + trainer.global_rank
        rows = [{"index": int(index[i]), "label": int(labels[i])} for i in range(n)]
        for scorer in self.scorers:
            for row, scores in zip(rows, scorer.score(recs, batch, index), strict=True):
                row.update(scores)
        self._rows[split] += rows
        if self.num_saved > 0:
            gt = _numpy(batch["eval_points"]) if "eval_points" in batch else np.zeros((n, 0, 3))
            saved = self._saved[split] + [(row["index"], recs[i], gt[i], row) for i, row in enumerate(rows)]
            self._saved[split] = sorted(saved, key=lambda item: item[0])[: self.num_saved]
        self._seen[split] += n

    def _finish_epoch(self, trainer, pl_module, split: str) -> None:
        # Collective: every rank gathers, also one that scored nothing.
        rows = {}
        for row in (row for rank_rows in _all_gather(trainer, self._rows[split]) for row in rank_rows):
            rows.setdefault(row["index"], row)  # a record a distributed sampler repeated counts once
        rows = [rows[i] for i in sorted(rows)]
        names = list(dict.fromkeys(key for row in rows for key in row if key not in ("index", "label")))
        labels = [row["label"] for row in rows] if self._names else None
        computed = pool_scores(rows, labels, max(1, len(self._names)), names)
        results = {name: {k: (v.reshape(-1) if k.startswith("class_") else v).tolist() for k, v in values.items()}
                   for name, values in computed.items()}  # torchmetrics squeezes one class to a scalar
        self.results[split] = results
        for name, values in results.items():
            self._log(pl_module, f"{split}/{name}", values["mean"], values["std"], values["count"])
            for c, class_name in enumerate(self._names):
                per_class = (values[f"class_{k}"][c] for k in ("mean", "std", "count"))
                self._log(pl_module, f"{split}/{class_name}/{name}", *per_class)
        saved = [item for rank_items in _all_gather(trainer, self._saved[split]) for item in rank_items]
        directory = self._epoch_dir(trainer, split)  # collective too: trainer.log_dir broadcasts
        if trainer.is_global_zero:
            self._write_rows(directory, rows)
            firsts = {}
            for item in sorted(saved, key=lambda item: item[0]):
                firsts.setdefault(item[0], item)
            for index, rec, gt_points, row in list(firsts.values())[: self.num_saved]:
                self._save(directory, rec, gt_points, index, row)

    @staticmethod
    def _log(pl_module, key: str, mean: float, std: float, count: float) -> None:
        # Every rank holds the same pooled values, so there is nothing left to reduce.
        if count > 0:  # nothing scored (e.g. IoU of point-set models): leave it absent, not NaN
            pl_module.log(f"{key}_mean", float(mean), sync_dist=False)
            pl_module.log(f"{key}_std", float(std), sync_dist=False)

    def _epoch_dir(self, trainer, split: str) -> Path:
        root = Path(self.save_dir or trainer.log_dir or trainer.default_root_dir)
        return root / "reconstructions" / split / f"epoch_{trainer.current_epoch:03d}"

    @staticmethod
    def _write_rows(directory: Path, rows: list[dict]) -> None:
        if not rows:
            return
        path = directory / "scores.csv"
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)

    @staticmethod
    def _save(directory: Path, rec, gt_points: np.ndarray, index: int, row: dict) -> None:
        directory.mkdir(parents=True, exist_ok=True)
        stem = directory / f"sample_{index:06d}"
        pred_points = prediction_surface(rec, PICTURE_POINTS, index)
        if rec is not None and rec.mesh is not None and len(pred_points):
            rec.mesh.export(stem.with_suffix(".obj"))
        elif rec is not None and rec.mesh is None and len(pred_points):
            trimesh.PointCloud(np.asarray(rec.points).reshape(-1, 3)).export(stem.with_suffix(".ply"))
        scores = {k: v for k, v in row.items() if k not in ("index", "label")}
        title = "  ".join(f"{k} {v:.4g}" for k, v in scores.items())
        save_comparison(stem.with_suffix(".png"), pred_points, gt_points, title=f"#{index}  {title}")
