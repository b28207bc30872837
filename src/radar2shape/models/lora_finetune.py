"""Fine-tune a PO-trained Stage 2 on higher-fidelity (SBR) radar with LoRA on the Transformer's q/v.

``LoRARadarDiffusion`` is a RadarDiffusion built from a base checkpoint's hyperparameters and
weights, with LoRA on its Transformer's attention projections and every other parameter frozen
(the paper's PO -> PO-SBR fine-tuning). Its own checkpoints hold the full RadarDiffusion
hyperparameters plus the LoRA settings, so they reload without the base checkpoint;
:meth:`merged_state_dict` gives weights that load into a plain RadarDiffusion.
"""

from __future__ import annotations

import copy

import torch

from radar2shape.errors import UserInputError
from radar2shape.models.base import check_hparam_names
from radar2shape.models.base import RADAR_SPEC_KEY
from radar2shape.models.radar_diffusion import RadarDiffusion
from radar2shape.nn.lora import apply_lora, load_base_state_dict, mark_only_lora_trainable, merge_lora
from radar2shape.radar.spec import RadarSpec

LORA_HPARAMS = ("base_ckpt", "base_source", "lora_rank", "lora_alpha", "lora_dropout", "lora_targets")


class LoRARadarDiffusion(RadarDiffusion):
    """RadarDiffusion with LoRA adapters; only the adapters train.

    Args:
        base_ckpt: PO-trained RadarDiffusion checkpoint (hyperparameters and weights are read once).
        lora_rank, lora_alpha, lora_dropout: adapter rank r, scale alpha / r, dropout on the input.
        lora_targets: attribute names of the wrapped nn.Linear layers inside ``transformer``.
        lr, weight_decay: AdamW settings of the fine-tuning (default: the base model's).
        base_source: provenance only (the base checkpoint path of the run that made this model).
        **hparams: RadarDiffusion arguments: ignored when ``base_ckpt`` is given (its own are used);
            given when a checkpoint of this class reloads (``base_ckpt`` None, weights in that checkpoint).
    """

    def __init__(self, base_ckpt: str | None = None, lora_rank: int = 4, lora_alpha: float = 8.0,
                 lora_dropout: float = 0.0, lora_targets: list[str] | tuple[str, ...] = ("q_proj", "v_proj"),
                 lr: float | None = None, weight_decay: float | None = None, base_source: str | None = None,
                 **hparams) -> None:
        state = None
        if base_ckpt is not None:
            try:
                ckpt = torch.load(base_ckpt, map_location="cpu", weights_only=True)
            except (OSError, RuntimeError) as err:
                raise UserInputError(f"base_ckpt: cannot read a checkpoint at {base_ckpt} ({err})") from err
            if "state_dict" not in ckpt or "stage1_hparams" not in ckpt.get("hyper_parameters", {}):
                raise UserInputError(f"base_ckpt: {base_ckpt} is not a RadarDiffusion checkpoint")
            check_hparam_names(ckpt["hyper_parameters"], f"base_ckpt {base_ckpt}")
            if ckpt.get(RADAR_SPEC_KEY) is None:
                raise UserInputError(f"base_ckpt: {base_ckpt} stores no radar spec (saved before checkpoints "
                                     "stored one); retrain the base model")
            # The base model's architecture wins: the CLI fills **hparams with RadarDiffusion's
            # defaults, which must not resize the model (only lr / weight_decay are fine-tuning settings).
            hparams = copy.deepcopy(dict(ckpt["hyper_parameters"]))
            state, base_source = ckpt["state_dict"], str(base_ckpt)
        elif hparams.get("stage1_hparams") is None:
            raise UserInputError("LoRARadarDiffusion needs base_ckpt (a PO-trained RadarDiffusion checkpoint)")
        # "_class_path" / "_instantiator": what LightningCLI adds to a checkpoint's hparams, not arguments
        hparams = {k: v for k, v in hparams.items() if k not in LORA_HPARAMS and not k.startswith("_")}
        hparams["stage1_ckpt"] = None  # Stage 1 comes from stage1_hparams and the weights
        for key, value in (("lr", lr), ("weight_decay", weight_decay)):
            if value is not None:
                hparams[key] = value
        super().__init__(**hparams)
        if state is not None:
            self.load_state_dict(state)
            self.radar_spec = RadarSpec.from_dict(ckpt[RADAR_SPEC_KEY], f"base_ckpt {base_ckpt}")
        targets = list(lora_targets)
        if not apply_lora(self.transformer, targets, lora_rank, lora_alpha, lora_dropout):
            raise UserInputError(f"lora_targets: no nn.Linear named {targets} in the Transformer")
        mark_only_lora_trainable(self)
        # hparams: the full RadarDiffusion set plus the LoRA settings (reloads without base_ckpt).
        # LightningCLI's own keys ("_class_path" = this class) stay: `test --ckpt_path` rebuilds the
        # model from them, and without "_class_path" it cannot parse the saved hyperparameters.
        for key in list(self.hparams):
            if key not in hparams and not key.startswith("_"):
                del self.hparams[key]
        self.hparams.update(hparams)
        self.hparams.update(base_ckpt=None, base_source=base_source, lora_rank=int(lora_rank),
                            lora_alpha=float(lora_alpha), lora_dropout=float(lora_dropout), lora_targets=targets)

    def merged_state_dict(self) -> dict:
        """Weights with the adapters folded in: loads strictly into ``RadarDiffusion(**base hparams)``."""
        merged = copy.deepcopy(self)
        merge_lora(merged)
        return merged.state_dict()

    def load_base_weights(self, state_dict: dict) -> None:
        """Load base (un-LoRA'd) weights; the adapters keep their values."""
        load_base_state_dict(self, state_dict)
