"""The base task every model (ours and baselines) is built on, and the reconstruction it returns.

``ReconstructionModel`` owns what all models share, once: the train/val/test steps and their
logging (from one :meth:`~ReconstructionModel.losses`), the optimizer and learning-rate schedule
(from hyperparameters), and the radar spec (grid + dB normalisation) that travels in every
checkpoint. A model keeps only what is its own: its networks, its losses and
:meth:`~ReconstructionModel.reconstruct`. Metric callbacks only talk to ``reconstruct``, so a
metric never knows which model it scores.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lightning as L
import torch
from lightning.pytorch.callbacks.weight_averaging import WeightAveraging
from torch.optim.swa_utils import get_ema_multi_avg_fn

from radar2shape.errors import UserInputError
from radar2shape.reconstruction import Reconstruction  # noqa: F401  (re-exported: the models' return type)

if TYPE_CHECKING:
    from radar2shape.radar.spec import RadarSpec

RADAR_SPEC_KEY = "radar_spec"

# Hyperparameters that now have one spelling across all models (old name -> new name).
RENAMED_HPARAMS = {
    "n_freq": "num_freq", "samples": "num_samples", "seed": "sample_seed", "d_model": "dim",
    "hidden": "mlp_hidden", "n_hidden": "mlp_layers", "n_samples": "chamfer_samples",
}


def check_hparam_names(hparams: dict, source: str) -> None:
    """Refuse hyperparameters saved under a retired spelling (a checkpoint of an older radar2shape)."""
    old = [f"{k} (now {v})" for k, v in RENAMED_HPARAMS.items() if k in hparams]
    if old:
        raise UserInputError(f"{source}: saved with retired hyperparameter names {', '.join(old)}; retrain the model")


def optimizer_options(params: list[torch.Tensor]) -> dict:
    """``fused=True`` where the fused Adam/AdamW kernel applies (float CPU/CUDA parameters, fast path on).

    The per-parameter loop of the default CPU implementation costs a Python-level op chain per
    tensor; the fused kernel updates each tensor in one pass (docs/throughput.md). Same update rule.
    """
    from radar2shape.nn.kernels import fast_enabled

    usable = all(p.device.type in ("cpu", "cuda") and p.dtype in (torch.float32, torch.float64) for p in params)
    return {"fused": True} if fast_enabled() and usable else {}


def batch_size_of(batch: dict) -> int:
    """Number of samples in a batch: the leading size of its first tensor."""
    for value in batch.values():
        if isinstance(value, torch.Tensor) and value.dim() > 0:
            return int(value.shape[0])
    raise ValueError(f"batch has no tensor to count samples from (keys: {sorted(batch)})")


class ForeachEMA(WeightAveraging):
    """An EMA of the weights updated after every step by one foreach lerp over all tensors.

    Lightning's ``EMAWeightAveraging`` averages the tensors one by one (about 400 small operations
    a Stage-2 step; bench/fit_steps.py, docs/throughput.md); the average is the same up to rounding.
    """

    def __init__(self, decay: float) -> None:
        super().__init__(multi_avg_fn=get_ema_multi_avg_fn(decay))


class ReconstructionModel(L.LightningModule):
    """A LightningModule that trains from :meth:`losses` and turns a batch into reconstructions.

    Subclasses implement :meth:`losses` (a dict with the total under ``"loss"``; empty for
    models that train nothing) and :meth:`reconstruct`. Optional hooks:
    :meth:`eval_losses` (deterministic losses for validation/test),
    :meth:`reconstruct_ceiling` (latent models: the first stage's bound on any reconstruction) and
    :meth:`check_radar_spec` (refuse a DataModule whose radar does not fit the network).

    Hyperparameters read here, with defaults for models that do not declare them: ``lr``,
    ``weight_decay``, ``lr_decay_steps`` (0: constant rate), ``lr_decay`` (step factor) and
    ``ema_decay`` (0: off; else validation, checkpoints and tests use an exponential moving average
    of the weights, Lightning's ``EMAWeightAveraging``).
    ``optimizer_class`` picks Adam or AdamW per model. ``reads_radar = False`` marks a model whose
    reconstruction ignores the radar (a Stage-1 autoencoder, the mean shape): its radar dependence
    is zero by construction, so the evaluator does not spend a second reconstruction measuring it.
    """

    optimizer_class: type[torch.optim.Optimizer] = torch.optim.AdamW
    radar_spec: RadarSpec | None = None
    reads_radar: bool = True

    # ---- what a model implements --------------------------------------------------------------
    def losses(self, batch: dict) -> dict[str, torch.Tensor]:
        """Loss terms of one training batch; the optimised total under ``"loss"``."""
        raise NotImplementedError(f"{type(self).__name__} must implement losses(batch)")

    def eval_losses(self, batch: dict, batch_idx: int) -> dict[str, torch.Tensor]:
        """Loss terms for validation and test; override to make them deterministic."""
        return self.losses(batch)

    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        """Return one :class:`Reconstruction` per sample of ``batch`` (same order)."""
        raise NotImplementedError(f"{type(self).__name__} must implement reconstruct(batch)")

    def reconstruct_ceiling(self, batch: dict) -> list[Reconstruction] | None:
        """The best this model's decoder can do for the batch's shapes, or None (default: no such bound).

        Latent models return their first stage's reconstruction of the true shapes (posterior means
        decoded): no sample of the second stage can score above it, so the evaluator reports it
        beside the model's own scores (docs/metrics.md, "Stage-1 ceiling").
        """
        return None

    def check_radar_spec(self, spec: RadarSpec) -> None:
        """Raise UserInputError when ``spec`` does not fit this network (default: accept)."""

    # ---- the Lightning steps, once -------------------------------------------------------------
    def _log_losses(self, stage: str, losses: dict[str, torch.Tensor], batch: dict) -> None:
        if not losses:
            return
        size = batch_size_of(batch)
        self.log_dict({f"{stage}/{k}": v.detach() for k, v in losses.items()},
                      on_step=stage == "train", on_epoch=True, batch_size=size, sync_dist=stage != "train")
        self.log(f"{stage}_loss", losses["loss"].detach(), prog_bar=True, logger=False, batch_size=size,
                 sync_dist=stage != "train")

    def training_step(self, batch: dict, batch_idx: int) -> torch.Tensor:
        from radar2shape.nn.kernels import training_autocast

        with training_autocast(self.device.type):
            losses = self.losses(batch)
        if "loss" not in losses:
            raise UserInputError(f"{type(self).__name__} has nothing to train; run it with `radar2shape test`")
        self._log_losses("train", losses, batch)
        return losses["loss"]

    def validation_step(self, batch: dict, batch_idx: int) -> None:
        self._log_losses("val", self.eval_losses(batch, batch_idx), batch)

    def test_step(self, batch: dict, batch_idx: int) -> None:
        """Logs the test losses; shape metrics come from the evaluator callback via ``reconstruct``."""
        self._log_losses("test", self.eval_losses(batch, batch_idx), batch)

    # ---- optimisation from hyperparameters -----------------------------------------------------
    def configure_optimizers(self):
        hp = self.hparams
        params = [p for p in self.parameters() if p.requires_grad]
        if not params:
            return None
        optimizer = self.optimizer_class(params, lr=float(hp.get("lr", 1e-3)),
                                         weight_decay=float(hp.get("weight_decay", 0.0)), **optimizer_options(params))
        decay_steps = int(hp.get("lr_decay_steps", 0) or 0)
        if decay_steps <= 0:
            return optimizer
        scheduler = torch.optim.lr_scheduler.StepLR(optimizer, decay_steps, gamma=float(hp.get("lr_decay", 0.5)))
        return {"optimizer": optimizer, "lr_scheduler": {"scheduler": scheduler, "interval": "step"}}

    def configure_callbacks(self):
        """The weight average of ``ema_decay`` while fitting (a checkpoint's ``state_dict`` is the average)."""
        decay = float(self.hparams.get("ema_decay", 0.0) or 0.0)
        if not 0.0 <= decay < 1.0:
            raise UserInputError(f"{type(self).__name__}: ema_decay must be in [0, 1), got {decay}")
        if decay == 0.0 or self._trainer is None or self.trainer.state.fn != "fit":
            return []
        return [ForeachEMA(decay)]

    # ---- the radar spec travels with the weights -----------------------------------------------
    def set_radar_spec(self, spec: RadarSpec | None) -> None:
        """Adopt the training data's radar spec (checked against the network first)."""
        if spec is not None:
            self.check_radar_spec(spec)
        self.radar_spec = spec

    def on_fit_start(self) -> None:
        """Take the radar spec from the DataModule, so every checkpoint of this fit stores it."""
        datamodule = getattr(self.trainer, "datamodule", None)
        spec = getattr(datamodule, "radar_spec", None)
        if spec is not None:
            self.set_radar_spec(spec)

    def on_save_checkpoint(self, checkpoint: dict) -> None:
        if self.radar_spec is not None:
            checkpoint[RADAR_SPEC_KEY] = self.radar_spec.to_dict()

    def on_load_checkpoint(self, checkpoint: dict) -> None:
        check_hparam_names(checkpoint.get("hyper_parameters", {}), f"{type(self).__name__} checkpoint")
        if checkpoint.get(RADAR_SPEC_KEY) is not None:
            from radar2shape.radar.spec import RadarSpec

            self.radar_spec = RadarSpec.from_dict(checkpoint[RADAR_SPEC_KEY])
