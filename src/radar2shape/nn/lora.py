"""Low-rank adaptation (Hu et al. 2021) of nn.Linear layers, for fine-tuning Stage 2 on SBR radar.

``LoRALinear`` subclasses nn.Linear and keeps the base ``weight``/``bias`` under their original
names, so a checkpoint of the plain model loads into the wrapped one (only the new ``lora_A`` /
``lora_B`` keys are missing: :func:`load_base_state_dict`), and :func:`merge_lora` gives back plain
nn.Linear layers whose state dict loads into the un-LoRA'd model.
"""

from __future__ import annotations

import math

import torch
from torch import nn
from torch.nn import functional as F

LORA_KEYS = ("lora_A", "lora_B")


class LoRALinear(nn.Linear):
    """y = base(x) + (alpha / rank) * B A dropout(x); B starts at zero so y = base(x) at init."""

    def __init__(self, base: nn.Linear, rank: int = 4, alpha: float = 8.0, dropout: float = 0.0) -> None:
        if rank < 1:
            raise ValueError(f"rank: expected an integer >= 1, got {rank}")
        factory = {"device": base.weight.device, "dtype": base.weight.dtype}
        super().__init__(base.in_features, base.out_features, bias=base.bias is not None, **factory)
        self.weight = base.weight  # share the base parameters (same tensors, same names)
        self.bias = base.bias
        self.rank, self.alpha = int(rank), float(alpha)
        self.scale = self.alpha / self.rank
        self.lora_A = nn.Parameter(torch.empty(self.rank, base.in_features, **factory))
        self.lora_B = nn.Parameter(torch.zeros(base.out_features, self.rank, **factory))
        nn.init.kaiming_uniform_(self.lora_A, a=math.sqrt(5))  # as nn.Linear's own init
        self.lora_dropout = nn.Dropout(dropout) if dropout > 0 else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        update = F.linear(F.linear(self.lora_dropout(x), self.lora_A), self.lora_B)
        return F.linear(x, self.weight, self.bias) + self.scale * update

    def merged(self) -> nn.Linear:
        """A plain nn.Linear with W + scale * B A (the base bias kept)."""
        factory = {"device": self.weight.device, "dtype": self.weight.dtype}
        out = nn.Linear(self.in_features, self.out_features, bias=self.bias is not None, **factory)
        with torch.no_grad():
            out.weight.copy_(self.weight + self.scale * (self.lora_B @ self.lora_A))
            if self.bias is not None:
                out.bias.copy_(self.bias)
        return out

    def extra_repr(self) -> str:
        return f"{super().extra_repr()}, rank={self.rank}, alpha={self.alpha:g}"


def _replace(module: nn.Module, name: str, new: nn.Module) -> None:
    parent, _, child = name.rpartition(".")
    setattr(module.get_submodule(parent) if parent else module, child, new)


def apply_lora(module: nn.Module, target_names=("q_proj", "v_proj"), rank: int = 4, alpha: float = 8.0,
               dropout: float = 0.0) -> list[str]:
    """Wrap every nn.Linear whose attribute name is in ``target_names``; returns their full names."""
    targets = set(target_names)
    found = [name for name, child in module.named_modules()
             if name.rpartition(".")[2] in targets and type(child) is nn.Linear]
    for name in found:
        _replace(module, name, LoRALinear(module.get_submodule(name), rank, alpha, dropout))
    return found


def mark_only_lora_trainable(module: nn.Module) -> int:
    """Freeze every parameter except the LoRA factors; returns the number of trainable values."""
    count = 0
    for name, param in module.named_parameters():
        param.requires_grad_(name.rpartition(".")[2] in LORA_KEYS)
        count += param.numel() if param.requires_grad else 0
    return count


def merge_lora(module: nn.Module) -> list[str]:
    """Fold every LoRALinear into a plain nn.Linear in place; returns the merged names."""
    found = [name for name, child in module.named_modules() if isinstance(child, LoRALinear)]
    for name in found:
        _replace(module, name, module.get_submodule(name).merged())
    return found


def load_base_state_dict(module: nn.Module, state_dict: dict) -> None:
    """Load a checkpoint of the un-LoRA'd model into a LoRA-wrapped ``module``.

    Strict except for the LoRA factors, which a base checkpoint does not have (they keep their
    initial values, so the wrapped model starts equal to the checkpoint).
    """
    result = module.load_state_dict(state_dict, strict=False)
    missing = [key for key in result.missing_keys if key.rpartition(".")[2] not in LORA_KEYS]
    if missing or result.unexpected_keys:
        raise RuntimeError(f"state dict mismatch: missing {missing[:5]}, unexpected {result.unexpected_keys[:5]}")
