"""The Lightning steps shared by the baselines that train one loss dictionary (TMNet, LIST).

Both models compute every term of their objective in ``losses(batch)`` (the total under
``"loss"``); logging each term under ``<stage>/<term>``, the empty ``test_step`` (scoring happens
in the metric callback through ``reconstruct``) and Adam on ``hparams.lr`` / ``weight_decay``
are the same code for both, so it lives here once.
"""

from __future__ import annotations

import torch


class LossDictSteps:
    """Mixin for a LightningModule with ``losses(batch) -> {"loss": total, term: value, ...}``."""

    def _step(self, stage: str, batch: dict) -> torch.Tensor:
        losses = self.losses(batch)
        self.log_dict({f"{stage}/{k}": v.detach() for k, v in losses.items()}, on_step=stage == "train",
                      on_epoch=True, prog_bar=False, batch_size=batch["radar"].shape[0])
        return losses["loss"]

    def training_step(self, batch: dict, batch_idx: int) -> torch.Tensor:
        return self._step("train", batch)

    def validation_step(self, batch: dict, batch_idx: int) -> None:
        self._step("val", batch)

    def test_step(self, batch: dict, batch_idx: int) -> None:
        """Scoring happens in the metric callback through ``reconstruct``."""

    def configure_optimizers(self):
        return torch.optim.Adam(self.parameters(), lr=self.hparams.lr, weight_decay=self.hparams.weight_decay)
