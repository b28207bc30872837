"""An object's heading read from its radar: whole roll-step turns about z, and the mirror y -> -y.

Turning an object about z by one roll step is an exact circular shift of its response along roll,
and mirroring it through the xz plane reverses roll (docs/design.md section 4). So a response can
be turned without re-simulating, and the turn that brings one response closest to another can be
found by trying all 2R of them. Training augmentation (``data_modules.augment``) turns records
this way; a model that reconstructs objects in their canonical heading uses :func:`estimate_turn`
to place its reconstruction in the observed heading.

A turn is ``(shift, mirror)``: the point map ``x -> Rz(shift * 2 pi / R) @ M @ x`` with
``M = diag(1, -1, 1)`` when ``mirror``. A real object is turned by any angle, not by whole steps:
:func:`refined_shift` reads a fractional shift off the correlations of the neighbouring turns.
"""

from __future__ import annotations

import math

import numpy as np

FLOOR_BELOW_PEAK_DB = 60.0  # dB maps are compared over [peak - 60 dB, peak]


def roll_steps(roll_rad) -> int:
    """R, after checking that the roll axis is R equal steps over the full circle, mirror-closed."""
    roll = np.asarray(roll_rad, dtype=np.float64).ravel()
    count = len(roll)
    step = 2.0 * np.pi / max(count, 1)
    if count < 1 or not np.allclose(np.diff(roll), step, atol=1e-9):
        raise ValueError("a turn needs a roll axis of equal steps covering [0, 2 pi)")
    half_steps = (2.0 * roll[0] / step) % 1.0
    if not (np.isclose(half_steps, 0.0, atol=1e-9) or np.isclose(half_steps, 1.0, atol=1e-9)):
        raise ValueError("a turn needs a roll axis that starts at a multiple of half a step (mirror symmetry)")
    return count


def roll_order(roll_rad, shift: int, mirror: bool) -> np.ndarray:
    """Index array ``order`` with ``turned[:, r] = response[:, order[r]]`` for the turn (shift, mirror)."""
    count = roll_steps(roll_rad)
    start_index = int(round(2.0 * float(np.ravel(roll_rad)[0]) / (2.0 * np.pi / count)))  # 2 * roll0 in steps
    order = np.arange(count)
    if mirror:  # p -> -p: the cell at roll index r takes the response at -r (shifted by the start offset)
        order = (-order - start_index) % count
    return np.roll(order, shift)


def turn_rotation(count: int, shift: float, mirror: bool) -> np.ndarray:
    """The 3x3 point map of the turn (shift, mirror) on a roll axis of ``count`` steps."""
    angle = 2.0 * np.pi * shift / count
    rotation = np.array([[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    return rotation @ np.diag([1.0, -1.0, 1.0]) if mirror else rotation


def candidate_turns(count: int) -> list[tuple[int, bool]]:
    """Every (shift, mirror) of a roll axis of ``count`` steps."""
    return [(shift, mirror) for mirror in (False, True) for shift in range(count)]


def power_db(response: np.ndarray) -> np.ndarray:
    """``10 log10 |E|^2`` of a complex response, floored ``FLOOR_BELOW_PEAK_DB`` below its peak."""
    db = 10.0 * np.log10(np.maximum(np.abs(response) ** 2, 1e-300))
    return np.maximum(db, db.max() - FLOOR_BELOW_PEAK_DB)


def band_averaged_db(db: np.ndarray) -> np.ndarray:
    """``[A, R, F]`` dB -> ``[A, R]`` dB of the power averaged over frequency.

    The average leaves out the fine interference pattern in frequency, which a smooth
    reconstruction does not reproduce, and keeps where along aspect and roll the object is bright.
    """
    peak = db.max()
    return peak + 10.0 * np.log10(np.mean(10.0 ** ((db - peak) / 10.0), axis=-1))


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two arrays of the same size (0 when either is constant)."""
    a, b = a.ravel() - a.mean(), b.ravel() - b.mean()
    norm = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / norm if norm > 0 else 0.0


def estimate_turn(observed_db: np.ndarray, candidate_db: np.ndarray, roll_rad, mask: np.ndarray | None = None,
                  band_average: bool = False) -> tuple[tuple[int, bool], np.ndarray]:
    """The turn of ``candidate_db`` ``[A, R, F]`` whose dB map correlates best with ``observed_db``.

    ``mask`` ``[A, R]`` (bool): compare observed cells only. Correlation, not a residual, so a level
    offset (size, calibration, a normalisation) does not matter. Returns the best turn and the
    correlation of every turn in :func:`candidate_turns` order.
    """
    if band_average:
        observed_db, candidate_db = band_averaged_db(observed_db), band_averaged_db(candidate_db)
    keep = np.ones(observed_db.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    turns = candidate_turns(roll_steps(roll_rad))
    target = observed_db[keep]
    scores = np.array([correlation(target, candidate_db[:, roll_order(roll_rad, s, m)][keep]) for s, m in turns])
    return turns[int(np.argmax(scores))], scores


def refined_shift(scores: np.ndarray, turn: tuple[int, bool], count: int) -> float:
    """The shift of ``turn`` moved to the vertex of the parabola through the correlations of the
    shifts one step either side (same mirror), within half a step: the heading between two steps."""
    shift, mirror = turn
    offset = count if mirror else 0
    left, centre, right = (scores[offset + (shift + d) % count] for d in (-1, 0, 1))
    curvature = left - 2.0 * centre + right
    if curvature >= 0:  # not a peak (flat or a tie): keep the whole step
        return float(shift)
    return float(shift + np.clip(0.5 * (left - right) / curvature, -0.5, 0.5))
