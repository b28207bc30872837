"""From a stored complex response to the network's radar input: noise, dB, mask, then the spec.

Order follows the paper: complex Gaussian noise is added to F before the dB conversion; the dB
image is standardised by the dataset's :class:`~radar2shape.radar.spec.RadarSpec` (the same
``normalise`` inference uses), which sets cells outside the observed window to 0 (the mean
after standardisation); the mask reports them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from radar2shape.errors import UserInputError
from radar2shape.radar.masks import MASK_RULES, fixed_window_mask, random_window_mask
from radar2shape.radar.signal import NOISE_REFERENCES, add_noise
from radar2shape.radar.spec import RadarSpec

NoiseLevel = float | tuple[float, float] | list[float] | None


def draw_noise_level(level: NoiseLevel, rng: np.random.Generator) -> float | None:
    """A fixed level, or one drawn uniformly in dB from a ``[low, high]`` range; None = no noise."""
    if level is None:
        return None
    if isinstance(level, (int, float)):
        return float(level)
    low, high = map(float, level)
    return float(rng.uniform(low, high))


@dataclass(frozen=True)
class RadarTransform:
    """One split's radar preprocessing: noise and observation windows; ``spec`` normalises.

    ``keep`` is a ``(min, max)`` range to draw windows from, or a fixed fraction with a per-sample
    fixed seed; ``mask_rule`` says what it is a fraction of (``per_axis``: of each axis, ``cells``:
    of the (aspect, roll) cells; radar2shape.radar.masks). ``noise_reference`` says what
    ``noise_db`` is relative to (``absolute``: dBsm, ``peak``: dB below each response's peak power).
    """

    spec: RadarSpec
    observability: str = "partial"  # "full": every cell observed
    keep: float | tuple[float, float] = 0.3
    noise_db: NoiseLevel = None
    mask_seed: int = 0
    mask_rule: str = "per_axis"
    noise_reference: str = "absolute"

    def __post_init__(self):
        if self.observability not in ("full", "partial"):
            raise UserInputError(f"observability: expected 'full' or 'partial', got {self.observability!r}")
        keep = (self.keep,) * 2 if isinstance(self.keep, (int, float)) else tuple(self.keep)
        if len(keep) != 2 or not 0.0 < keep[0] <= keep[1] <= 1.0:
            raise UserInputError(f"keep: expected a fraction in (0, 1] or a [low, high] range of them, "
                                 f"got {self.keep!r}")
        if self.mask_rule not in MASK_RULES:
            raise UserInputError(f"mask_rule: expected one of {', '.join(MASK_RULES)}, got {self.mask_rule!r}")
        if self.noise_reference not in NOISE_REFERENCES:
            raise UserInputError(f"noise_reference: expected one of {', '.join(NOISE_REFERENCES)}, "
                                 f"got {self.noise_reference!r}")

    def mask(self, n_aspect: int, n_roll: int, rng: np.random.Generator, index: int) -> np.ndarray:
        """Observed cells ``[A, R]``: one contiguous aspect x roll window (roll wraps around)."""
        if self.observability == "full":
            return np.ones((n_aspect, n_roll), dtype=bool)
        if isinstance(self.keep, (int, float)):
            return fixed_window_mask(n_aspect, n_roll, float(self.keep), self.mask_seed + index, self.mask_rule)
        low, high = map(float, self.keep)
        return random_window_mask(n_aspect, n_roll, low, high, rng, self.mask_rule)

    def __call__(self, response: np.ndarray, rng: np.random.Generator, index: int) -> tuple[np.ndarray, np.ndarray]:
        """``(radar float32 [A, R, F], mask bool [A, R])`` from a complex ``response [A, R, F]``."""
        level = draw_noise_level(self.noise_db, rng)
        if level is not None:
            response = add_noise(response, level, rng, self.noise_reference)
        db = self.spec.to_db(response)
        mask = self.mask(response.shape[0], response.shape[1], rng, index)
        return self.spec.normalise(db, mask), mask
