"""The one switch between the fast training kernels and the reference ops they replace.

The fast forms live beside their reference in the module that owns the op (plane pooling in
``nn.triplane``, nearest neighbours in ``baselines.point_losses``, LIST's query context, the fused
optimizer in ``models.base``); each checks :func:`fast_enabled`. The reference ops are kept: they
are the definitions the tests compare against, and :func:`reference_path` restores them for a speed
comparison in the same process (``bench/train_throughput.py``). Every fast form computes the same
function in float32 up to rounding and changes no parameter, so checkpoints are unaffected.
bfloat16 autocast is separate and opt-in (:func:`set_bf16_training`): it changes the numerics.
Measurements: docs/throughput.md.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator

import torch

_FAST = True


def fast_enabled() -> bool:
    """True when the fused kernels are in use (the default)."""
    return _FAST


def set_fast(enabled: bool) -> None:
    """Select the fused kernels (True) or the reference ops (False) for every model, process-wide."""
    global _FAST
    _FAST = bool(enabled)


@contextlib.contextmanager
def reference_path(enabled: bool = True) -> Iterator[None]:
    """Run the enclosed code on the reference ops (``enabled=False``: leave the switch as it is)."""
    previous = _FAST
    if enabled:
        set_fast(False)
    try:
        yield
    finally:
        set_fast(previous)


_BF16_TRAINING = False


def set_bf16_training(enabled: bool) -> None:
    """Opt in to bfloat16 autocast of the training losses on CPU (off by default: not a refactor,
    it changes the numerics; docs/throughput.md has its speed-up and what was checked)."""
    global _BF16_TRAINING
    _BF16_TRAINING = bool(enabled)


def bf16_training() -> bool:
    """Whether the bfloat16 training opt-in is on."""
    return _BF16_TRAINING


@functools.lru_cache(maxsize=1)
def cpu_has_bf16() -> bool:
    """True when this CPU has native bfloat16 dot products (AVX512-BF16 or AMX), where autocast pays."""
    try:
        flags = open("/proc/cpuinfo").read()
    except OSError:
        return False
    return " avx512_bf16" in flags or " amx_bf16" in flags


def training_autocast(device_type: str) -> contextlib.AbstractContextManager:
    """The autocast context of one training step: bfloat16 on a bf16-capable CPU when opted in, else none.

    "None" is a null context, not ``autocast(enabled=False)``: that would switch off an autocast the
    trainer opened around the step (``precision: bf16-mixed`` on a CPU).
    """
    if _FAST and _BF16_TRAINING and device_type == "cpu" and cpu_has_bf16():
        return torch.autocast("cpu", dtype=torch.bfloat16)
    return contextlib.nullcontext()
