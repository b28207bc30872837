"""Cache Stage-1 posteriors to a file so Stage 2 trains on latents without re-running the encoder.

Used by ``radar2shape predict --config conf/trainer/gpu.yaml --config conf/callbacks/shape_metrics.yaml --config conf/experiment/sdf_vae_parts.yaml --ckpt_path CKPT``:
the SDF-VAE's ``predict_step`` returns ``{"mu", "logvar", "index"}`` per batch and this writer
saves, at the end of the epoch, one ``torch.save`` file of plain tensors (loadable with
``torch.load(weights_only=True)``)::

    {"mu": float [N, L, Z], "logvar": float [N, L, Z], "index": int64 [N]}   # sorted by index

``index`` is the record index within the predicted split (the batch key ``index``). Under DDP
each rank writes ``<stem>_rank<r><suffix>`` (merge by index).
"""

from __future__ import annotations

from pathlib import Path

import torch
from lightning.pytorch.callbacks import BasePredictionWriter

from radar2shape.atomic import atomic_open

LATENT_KEYS = ("mu", "logvar", "index")


def merge_latents(predictions: list[dict]) -> dict[str, torch.Tensor]:
    """Concatenate per-batch prediction dicts and sort them by record index."""
    merged = {key: torch.cat([p[key].detach().cpu() for p in predictions]) for key in LATENT_KEYS}
    order = torch.argsort(merged["index"])
    return {key: value[order] for key, value in merged.items()}


class LatentWriter(BasePredictionWriter):
    """Write the predicted posteriors of every record to ``output_path`` (a ``.pt`` file)."""

    def __init__(self, output_path: str = "latents.pt") -> None:
        super().__init__(write_interval="epoch")
        self.output_path = output_path

    def _path(self, trainer) -> Path:
        path = Path(self.output_path)
        if trainer.world_size > 1:
            path = path.with_name(f"{path.stem}_rank{trainer.global_rank}{path.suffix}")
        return path

    def write_on_epoch_end(self, trainer, pl_module, predictions, batch_indices) -> None:
        batches = predictions[0] if predictions and isinstance(predictions[0], list) else predictions
        if not batches:
            return
        missing = [k for k in LATENT_KEYS if k not in batches[0]]
        if missing:
            raise KeyError(f"LatentWriter needs predict_step outputs with keys {list(LATENT_KEYS)}; missing {missing}")
        path = self._path(trainer)
        with atomic_open(path, "wb") as handle:  # a reader never sees half a file
            torch.save(merge_latents(batches), handle)
