"""Fused CPU kernels for the training hot spots, and the one switch between them and the reference ops.

The reference ops (per-level ``grid_sample`` calls, a ``scatter_add`` per plane and block, dense
``[B, N, M]`` distance graphs in the autograd tape) are kept: they are the definitions the tests
check against, and ``reference_path()`` restores them for a speed comparison in the same process
(``bench/train_throughput.py``). Every fused kernel computes the same function in float32 up to
rounding; none changes a parameter, so checkpoints are unaffected. Measurements: docs/throughput.md.

The fused forms rest on one observation: a bilinear/trilinear read of any set of grids is a
weighted sum of rows of one ``[rows, C]`` table, which ``F.embedding_bag(mode="sum")`` evaluates
in one pass, forward and backward, with the corner weights as ``per_sample_weights``.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator

import torch
import torch.nn.functional as F

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


def weighted_rows(table: torch.Tensor, index: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """``out[i] = sum_k weights[i, k] * table[index[i, k]]``: ``table [T, C]``, ``index, weights [M, K]`` -> ``[M, C]``.

    Differentiable in ``table`` and ``weights`` (so also in the points the weights come from).
    """
    return F.embedding_bag(index.reshape(index.shape[0], -1), table, per_sample_weights=weights.reshape(index.shape[0], -1),
                           mode="sum")


def bilinear_corners(uv: torch.Tensor, resolution: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Flat pixel indices ``[..., 4]`` (``row * R + col``) and weights ``[..., 4]`` of a bilinear read.

    ``uv [..., 2]`` in ``[-1, 1]`` (x = column, y = row), the convention of ``F.grid_sample`` with
    ``align_corners=False`` and ``padding_mode="border"``: pixel centres at cell centres, reads beyond
    the outer centres clamped onto them.
    """
    pix = ((uv + 1) * resolution - 1) * 0.5
    pix = pix.clamp(0, resolution - 1)
    base = pix.detach().floor().clamp(max=resolution - 1)
    frac = pix - base
    lo = base.long()
    hi = (lo + 1).clamp(max=resolution - 1)
    x0, y0, x1, y1 = lo[..., 0], lo[..., 1], hi[..., 0], hi[..., 1]
    fx, fy = frac[..., 0], frac[..., 1]
    index = torch.stack([y0 * resolution + x0, y0 * resolution + x1, y1 * resolution + x0, y1 * resolution + x1], -1)
    weights = torch.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy], -1)
    return index, weights


_BF16_TRAINING = False


def set_bf16_training(enabled: bool) -> None:
    """Opt in to bfloat16 autocast of the training losses on CPU (off by default: not a refactor,
    it changes the numerics; docs/throughput.md has its speed-up and what was checked)."""
    global _BF16_TRAINING
    _BF16_TRAINING = bool(enabled)


@functools.lru_cache(maxsize=1)
def cpu_has_bf16() -> bool:
    """True when this CPU has native bfloat16 dot products (AVX512-BF16 or AMX), where autocast pays."""
    try:
        flags = open("/proc/cpuinfo").read()
    except OSError:
        return False
    return " avx512_bf16" in flags or " amx_bf16" in flags


def training_autocast(device_type: str) -> contextlib.AbstractContextManager:
    """The autocast context of one training step: bfloat16 on a bf16-capable CPU when opted in, else none."""
    enabled = _FAST and _BF16_TRAINING and device_type == "cpu" and cpu_has_bf16()
    return torch.autocast("cpu", dtype=torch.bfloat16, enabled=enabled)
