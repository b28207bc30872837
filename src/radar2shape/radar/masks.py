"""Partial observability: which (aspect, roll) cells the radar saw (docs/design.md section 2).

A mask is bool [A, R], True = observed, the product of one contiguous window per axis. The
aspect window never wraps (aspect runs 0..pi); the roll window may wrap past 2 pi because roll
is circular. Each axis keeps a fraction of its bins within [min_keep, max_keep].
"""

from __future__ import annotations

import math

import numpy as np

from radar2shape.errors import UserInputError


def _window_length(n: int, min_keep: float, max_keep: float, rng: np.random.Generator) -> int:
    """Uniform over the bin counts whose fraction lies in [min_keep, max_keep].

    When no integer count fits (tiny axes), the count nearest the middle of the range is used.
    """
    lo, hi = max(1, math.ceil(min_keep * n - 1e-9)), min(n, math.floor(max_keep * n + 1e-9))
    if lo > hi:
        return min(n, max(1, round(n * (min_keep + max_keep) / 2)))
    return int(rng.integers(lo, hi + 1))


def _check(n_aspect: int, n_roll: int, min_keep: float, max_keep: float) -> None:
    for name, n in (("n_aspect", n_aspect), ("n_roll", n_roll)):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise UserInputError(f"{name}: expected a positive integer, got {n!r}")
    if not 0.0 < min_keep <= max_keep <= 1.0:
        raise UserInputError(f"keep fractions: expected 0 < min_keep <= max_keep <= 1, got {min_keep}, {max_keep}")


def random_window_mask(n_aspect: int, n_roll: int, min_keep: float, max_keep: float,
                       rng: np.random.Generator | int | None = None) -> np.ndarray:
    """bool [A, R]: a random contiguous aspect window times a random (wrapping) roll window."""
    _check(n_aspect, n_roll, min_keep, max_keep)
    rng = np.random.default_rng(rng)
    length = _window_length(n_aspect, min_keep, max_keep, rng)
    start = int(rng.integers(0, n_aspect - length + 1))
    aspect = np.zeros(n_aspect, dtype=bool)
    aspect[start : start + length] = True
    length = _window_length(n_roll, min_keep, max_keep, rng)
    start = int(rng.integers(0, n_roll))
    roll = np.zeros(n_roll, dtype=bool)
    roll[(start + np.arange(length)) % n_roll] = True
    return aspect[:, None] & roll[None, :]


def fixed_window_mask(n_aspect: int, n_roll: int, keep: float, seed: int = 0) -> np.ndarray:
    """The test-time mask: each axis keeps ``keep`` of its bins, placed by ``seed`` (reproducible)."""
    return random_window_mask(n_aspect, n_roll, keep, keep, np.random.default_rng(seed))
