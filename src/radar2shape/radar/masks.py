"""Partial observability: which (aspect, roll) cells the radar saw (docs/data.md, "Observability and noise").

A mask is bool [A, R], True = observed: one contiguous aspect window times one roll window. The
aspect window never wraps (aspect runs 0..pi); the roll window may wrap past 2 pi because roll
is circular. Two rules say how large the window is, given a kept fraction ``keep``:

- ``per_axis``: each axis keeps ``keep`` of its bins, so ``keep**2`` of the cells stay observed
  (``keep = 0.3`` observes ~9 % of the cells);
- ``cells`` (the paper's "mask on 70 % of the signal"): the window holds ``keep`` of the cells; its
  aspect and roll lengths are drawn among the pairs whose product is nearest ``keep * A * R``.

With one roll bin (aspect-only, roll-symmetric data) both rules give the same window: ``keep``
of the aspects, i.e. ``keep`` of the signal.
"""

from __future__ import annotations

import math

import numpy as np

from radar2shape.errors import UserInputError

MASK_RULES = ("per_axis", "cells")


def _window_length(n: int, min_keep: float, max_keep: float, rng: np.random.Generator) -> int:
    """Uniform over the bin counts whose fraction lies in [min_keep, max_keep].

    When no integer count fits (tiny axes), the count nearest the middle of the range is used.
    """
    lo, hi = max(1, math.ceil(min_keep * n - 1e-9)), min(n, math.floor(max_keep * n + 1e-9))
    if lo > hi:
        return min(n, max(1, round(n * (min_keep + max_keep) / 2)))
    return int(rng.integers(lo, hi + 1))


def _check(n_aspect: int, n_roll: int, min_keep: float, max_keep: float, rule: str) -> None:
    for name, n in (("n_aspect", n_aspect), ("n_roll", n_roll)):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise UserInputError(f"{name}: expected a positive integer, got {n!r}")
    if not 0.0 < min_keep <= max_keep <= 1.0:
        raise UserInputError(f"keep fractions: expected 0 < min_keep <= max_keep <= 1, got {min_keep}, {max_keep}")
    if rule not in MASK_RULES:
        raise UserInputError(f"mask_rule: expected one of {', '.join(MASK_RULES)}, got {rule!r}")


def cells_window_size(n_aspect: int, n_roll: int, target: float,
                      rng: np.random.Generator | int | None = None) -> tuple[int, int]:
    """(aspect length, roll length) whose product is nearest ``target`` cells; ties drawn uniformly.

    Drawing among all nearest pairs (tall, wide and square windows alike) keeps the window's shape
    from favouring one axis.
    """
    lengths = np.arange(1, n_aspect + 1)[:, None] * np.arange(1, n_roll + 1)[None, :]
    error = np.abs(lengths - target)
    ties = np.argwhere(error <= error.min() + 1e-9)
    pick = ties[0] if len(ties) == 1 else ties[np.random.default_rng(rng).integers(len(ties))]
    return int(pick[0]) + 1, int(pick[1]) + 1


def _aspect_window(n: int, length: int, rng: np.random.Generator) -> np.ndarray:
    window = np.zeros(n, dtype=bool)
    start = int(rng.integers(0, n - length + 1))
    window[start : start + length] = True
    return window


def _roll_window(n: int, length: int, rng: np.random.Generator) -> np.ndarray:
    window = np.zeros(n, dtype=bool)
    window[(int(rng.integers(0, n)) + np.arange(length)) % n] = True  # roll is circular: may wrap
    return window


def random_window_mask(n_aspect: int, n_roll: int, min_keep: float, max_keep: float,
                       rng: np.random.Generator | int | None = None, rule: str = "per_axis") -> np.ndarray:
    """bool [A, R]: one random contiguous aspect x (wrapping) roll window keeping a fraction in the range.

    ``per_axis`` draws each axis' kept count uniformly; ``cells`` draws the kept cell count uniformly
    (the exact ``keep * A * R`` when ``min_keep == max_keep``) and then the window's shape.
    """
    _check(n_aspect, n_roll, min_keep, max_keep, rule)
    rng = np.random.default_rng(rng)
    if rule == "per_axis" or n_roll == 1:  # one roll bin: the rules coincide, keep the per-axis draws
        aspect = _aspect_window(n_aspect, _window_length(n_aspect, min_keep, max_keep, rng), rng)
        roll = _roll_window(n_roll, _window_length(n_roll, min_keep, max_keep, rng), rng)
    else:
        cells = n_aspect * n_roll
        target = min_keep * cells if min_keep == max_keep else _window_length(cells, min_keep, max_keep, rng)
        a_len, r_len = cells_window_size(n_aspect, n_roll, target, rng)
        aspect, roll = _aspect_window(n_aspect, a_len, rng), _roll_window(n_roll, r_len, rng)
    return aspect[:, None] & roll[None, :]


def fixed_window_mask(n_aspect: int, n_roll: int, keep: float, seed: int = 0, rule: str = "per_axis") -> np.ndarray:
    """The test-time mask: a window keeping ``keep`` (per axis or of the cells), placed by ``seed``."""
    return random_window_mask(n_aspect, n_roll, keep, keep, np.random.default_rng(seed), rule)
