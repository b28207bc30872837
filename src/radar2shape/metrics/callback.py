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

Two diagnostics run on the test split by default (docs/metrics.md): the **radar dependence**
(each shape reconstructed a second time from another shape's radar, scored against its own
truth: ``radar_dependence_<metric>`` = own minus swapped, logged with ``_mean``, ``_std`` and the
standard error ``_se``) and the **ceiling** of models with a ``reconstruct_ceiling`` hook
(``ceiling_<metric>``). Every metric also logs ``_count`` (shapes that scored it) beside
``num_shapes`` (shapes evaluated), and ``num_surface_points`` / ``num_occ_points`` say at which
sampling the shape metrics were taken.
"""

from __future__ import annotations

import csv
import math
import time
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
DEPENDENCE = "radar_dependence_"  # row prefix: own-radar score minus swapped-radar score
CEILING = "ceiling_"  # row prefix: scores of the model's reconstruct_ceiling
RADAR_KEYS = ("radar", "radar_mask")  # what the swap exchanges between shapes


def _numpy(value) -> np.ndarray:
    return value.detach().cpu().numpy() if isinstance(value, torch.Tensor) else np.asarray(value)


def take(batch: dict, rows: slice) -> dict:
    """The samples ``rows`` of a batch: every per-sample tensor (or list) sliced, the rest kept."""
    size = batch_size_of(batch)
    out = {}
    for key, value in batch.items():
        sized = isinstance(value, list | tuple) or (isinstance(value, torch.Tensor) and value.dim() > 0)
        per_sample = sized and len(value) == size
        out[key] = value[rows] if per_sample else value
    return out


# (confidence, score) pairs whose Spearman rank correlation over the shapes is logged when both are scored:
# how well a score that needs no ground truth says which reconstructions are poor.
RANKED = (("radar_consistency", "iou"), ("predicted_iou", "iou"))
PREDICTED_IOU = "predicted_iou"  # row key of a reconstruction's own IoU estimate (Reconstruction.predicted_iou)


def rank_correlation(rows: list[dict], a: str, b: str) -> float | None:
    """Spearman's rho of ``a`` against ``b`` over the rows holding finite values of both (None: < 3 rows)."""
    from scipy.stats import spearmanr

    pairs = [(row[a], row[b]) for row in rows if a in row and b in row]
    pairs = [(x, y) for x, y in pairs if math.isfinite(x) and math.isfinite(y)]
    if len(pairs) < 3:
        return None
    rho = spearmanr(*zip(*pairs)).statistic
    return float(rho) if math.isfinite(rho) else None


def standard_error(std: float, count: float) -> float:
    """Standard error of a mean from the population std (ddof 0) of ``count`` values: std / sqrt(n - 1)."""
    return std / math.sqrt(count - 1) if count > 1 else math.nan


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
        radar_dependence: also reconstruct every scored shape from another shape's radar and
            log own minus swapped per metric (``radar_dependence_<metric>``). The pairing is a
            fixed derangement of the scored shapes in record-index order: each shape gets the
            radar and radar mask of the shape before it, the first that of the last, whatever
            the batch size and the number of processes; a split of one shape has none.
        ceiling: score ``pl_module.reconstruct_ceiling(batch)`` as ``ceiling_<metric>`` when
            the model has the hook and it returns reconstructions (latent models: Stage 1's
            posterior means decoded).
        diagnostics_on_val: run the two diagnostics on validation too (default: test only; each
            costs about one more reconstruction per shape).

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
        radar_dependence: bool = True,
        ceiling: bool = True,
        diagnostics_on_val: bool = False,
    ):
        super().__init__()
        self.scorers = list(scorers) if scorers else [ShapeScorer()]
        self.every_n_epochs, self.val_max_samples = max(1, int(every_n_epochs)), val_max_samples
        self.num_saved, self.class_names, self.save_dir = int(num_saved), class_names, save_dir
        self.radar_dependence, self.ceiling = bool(radar_dependence), bool(ceiling)
        self.diagnostics_on_val = bool(diagnostics_on_val)
        self.results: dict[str, dict[str, dict]] = {}  # last computed, per split
        self.counts: dict[str, dict[str, int]] = {}  # shapes evaluated and sampling sizes, per split
        self._start_all()

    # -- Lightning hooks -------------------------------------------------------------------
    def setup(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        if not callable(getattr(pl_module, "reconstruct", None)):
            name = type(pl_module).__name__
            raise TypeError(f"ReconstructionEvaluator needs a ReconstructionModel; {name} has no reconstruct(batch)")
        names = self.class_names or getattr(getattr(trainer, "datamodule", None), "class_names", None)
        self._names = [str(n) for n in names] if names else []
        for scorer in self.scorers:
            scorer.setup(trainer, pl_module)
        self._start_all()

    def _start_all(self) -> None:
        self._seen = dict.fromkeys(SPLITS, 0)
        self._rows: dict[str, list[dict]] = {s: [] for s in SPLITS}
        self._saved: dict[str, list[tuple]] = {s: [] for s in SPLITS}  # (index, rec, gt points, row)
        self._counts: dict[str, dict[str, int]] = {s: {} for s in SPLITS}  # sampling sizes, min over batches
        self._pending: dict[str, list] = {s: [] for s in SPLITS}  # (samples, index, rows) awaiting their swap
        self._radars: dict[str, dict] = {s: {} for s in SPLITS}  # record index -> its radar keys (CPU)

    def on_fit_start(self, trainer, pl_module) -> None:
        self._fit_started = time.perf_counter()

    def on_validation_epoch_start(self, trainer, pl_module) -> None:
        self._start_epoch("val")
        # wall seconds of this sitting's fit when validation began: learning curves against time
        started = getattr(self, "_fit_started", None)
        self._val_at_seconds = None if started is None else time.perf_counter() - started

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
            if getattr(self, "_val_at_seconds", None) is not None:
                pl_module.log("val/fit_seconds", float(self._val_at_seconds), sync_dist=False)

    def on_test_epoch_end(self, trainer, pl_module) -> None:
        self._finish_epoch(trainer, pl_module, "test")

    # -- work ------------------------------------------------------------------------------
    def _scoring_val(self, trainer: L.Trainer) -> bool:
        return not trainer.sanity_checking and (trainer.current_epoch + 1) % self.every_n_epochs == 0

    def _start_epoch(self, split: str) -> None:
        self._seen[split] = 0
        self._rows[split] = []
        self._saved[split] = []
        self._counts[split] = {}
        self._pending[split], self._radars[split] = [], {}

    def _diagnosing(self, split: str) -> bool:
        return split == "test" or self.diagnostics_on_val

    def _score(self, recs: list, batch: dict, index: np.ndarray) -> list[dict]:
        """Every scorer's scores of ``recs`` against ``batch``'s ground truth, one dict per sample."""
        rows = [{} for _ in recs]
        for scorer in self.scorers:
            for row, scores in zip(rows, scorer.score(recs, batch, index), strict=True):
                row.update(scores)
        return rows

    @staticmethod
    def _reconstruct(pl_module, batch: dict, method: str = "reconstruct") -> list | None:
        recs = getattr(pl_module, method)(batch)
        if recs is None:
            return None
        recs, size = list(recs), batch_size_of(batch)
        if len(recs) != size:
            name = type(pl_module).__name__
            raise ValueError(f"{name}.{method} returned {len(recs)} reconstructions for a batch of {size}")
        return recs

    def _evaluate(self, trainer, pl_module, batch: dict, split: str, limit: int | None) -> None:
        for scorer in self.scorers:
            scorer.check(batch)
        recs = self._reconstruct(pl_module, batch)[:limit]
        n = len(recs)
        labels = _numpy(batch["label"]).reshape(-1)[:n] if "label" in batch else np.zeros(n, dtype=np.int64)
        if "index" in batch:
            index = _numpy(batch["index"]).reshape(-1)[:n]
        else:  # the position in the split under an interleaving distributed sampler
            index = (self._seen[split] + np.arange(n)) * trainer.world_size + trainer.global_rank
        rows = [{"index": int(index[i]), "label": int(labels[i])} for i in range(n)]
        for row, scores, rec in zip(rows, self._score(recs, batch, index), recs):
            row.update(scores)
            if getattr(rec, PREDICTED_IOU, None) is not None:
                row[PREDICTED_IOU] = float(rec.predicted_iou)
        for scorer in self.scorers:
            for key, count in scorer.counts(batch).items():
                self._counts[split][key] = min(count, self._counts[split].get(key, count))
        if n and self._diagnosing(split):
            scored = take(batch, slice(0, n))
            if self.ceiling and callable(getattr(pl_module, "reconstruct_ceiling", None)):
                ceiling = self._reconstruct(pl_module, scored, "reconstruct_ceiling")
                for row, scores in zip(rows, self._score(ceiling, scored, index) if ceiling is not None else []):
                    row.update({CEILING + k: v for k, v in scores.items()})
            if self.radar_dependence and "radar" in batch and getattr(pl_module, "reads_radar", True):
                self._swap(pl_module, scored, index, rows, split)
        self._rows[split] += rows
        if self.num_saved > 0:
            gt = _numpy(batch["eval_points"]) if "eval_points" in batch else np.zeros((n, 0, 3))
            saved = self._saved[split] + [(row["index"], recs[i], gt[i], row) for i, row in enumerate(rows)]
            self._saved[split] = sorted(saved, key=lambda item: item[0])[: self.num_saved]
        self._seen[split] += n

    def _swap(self, pl_module, scored: dict, index: np.ndarray, rows: list[dict], split: str) -> None:
        """Keep the samples and their radar: the swap needs every process's radars (epoch end)."""
        cpu = {key: value.detach().cpu() if isinstance(value, torch.Tensor) else value for key, value in scored.items()}
        self._pending[split].append((cpu, index, rows))
        for k, i in enumerate(index):
            self._radars[split][int(i)] = {key: cpu[key][k] for key in RADAR_KEYS if key in cpu}

    def _add_dependence(self, pl_module, targets: dict, radar: dict, index: np.ndarray, rows: list[dict]) -> None:
        swapped = self._score(self._reconstruct(pl_module, {**targets, **radar}), targets, index)
        for row, scores in zip(rows, swapped):
            row.update({DEPENDENCE + k: row[k] - v for k, v in scores.items() if k in row})

    def _resolve_swaps(self, trainer, pl_module, split: str) -> None:
        """Reconstruct each kept sample from the radar of the shape before it in record-index order
        (the first from the last): a fixed derangement of the split, the same on any number of
        processes. Collective: every rank gathers the radars, also one that scored nothing."""
        if not (self.radar_dependence and self._diagnosing(split)):
            return
        pool = {}
        for radars in _all_gather(trainer, self._radars[split]):
            pool.update(radars)
        pending, self._pending[split], self._radars[split] = self._pending[split], [], {}
        order = sorted(pool)
        if len(order) < 2:  # one shape has no other radar to swap in
            return
        partner = {i: order[k - 1] for k, i in enumerate(order)}
        device = pl_module.device
        for samples, index, rows in pending:
            targets = {k: v.to(device) if isinstance(v, torch.Tensor) else v for k, v in samples.items()}
            radar = {key: torch.stack([pool[partner[int(i)]][key] for i in index]).to(device)
                     for key in RADAR_KEYS if key in targets}
            self._add_dependence(pl_module, targets, radar, index, rows)

    def _finish_epoch(self, trainer, pl_module, split: str) -> None:
        self._resolve_swaps(trainer, pl_module, split)
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
        for name, values in results.items():
            if name.startswith(DEPENDENCE):
                values["se"] = standard_error(values["std"], values["count"])
        counts = {}
        for rank_counts in _all_gather(trainer, self._counts[split]):
            for key, count in rank_counts.items():
                counts[key] = min(count, counts.get(key, count))
        self.results[split] = results
        self.counts[split] = {"num_shapes": len(rows), **counts}
        for name, values in results.items():
            self._log(pl_module, f"{split}/{name}", values["mean"], values["std"], values["count"], values.get("se"))
            for c, class_name in enumerate(self._names):
                per_class = (values[f"class_{k}"][c] for k in ("mean", "std", "count"))
                self._log(pl_module, f"{split}/{class_name}/{name}", *per_class)
        for confidence, score in RANKED:
            rho = rank_correlation(rows, confidence, score)
            if rho is not None:
                pl_module.log(f"{split}/spearman_{confidence}_{score}", rho, sync_dist=False)
        if rows:
            for key, count in self.counts[split].items():
                pl_module.log(f"{split}/{key}", float(count), sync_dist=False)
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
    def _log(pl_module, key: str, mean: float, std: float, count: float, se: float | None = None) -> None:
        # Every rank holds the same pooled values, so there is nothing left to reduce.
        if count > 0:  # nothing scored (e.g. IoU of point-set models): leave it absent, not NaN
            pl_module.log(f"{key}_mean", float(mean), sync_dist=False)
            pl_module.log(f"{key}_std", float(std), sync_dist=False)
            pl_module.log(f"{key}_count", float(count), sync_dist=False)
            if se is not None and not math.isnan(se):
                pl_module.log(f"{key}_se", float(se), sync_dist=False)

    def _epoch_dir(self, trainer, split: str) -> Path:
        root = Path(self.save_dir or trainer.log_dir or trainer.default_root_dir)
        return root / "reconstructions" / split / f"epoch_{trainer.current_epoch:03d}"

    @staticmethod
    def _write_rows(directory: Path, rows: list[dict]) -> None:
        if not rows:
            return
        path = directory / "scores.csv"
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", newline="") as handle:  # a shape without a swap partner leaves its cells empty
            writer = csv.DictWriter(handle, fieldnames=list(dict.fromkeys(k for row in rows for k in row)), restval="")
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
        scores = {k: v for k, v in row.items() if k not in ("index", "label") and not k.startswith((DEPENDENCE, CEILING))}
        title = "  ".join(f"{k} {v:.4g}" for k, v in scores.items())
        save_comparison(stem.with_suffix(".png"), pred_points, gt_points, title=f"#{index}  {title}")
