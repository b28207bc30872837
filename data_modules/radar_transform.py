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
from radar2shape.radar import add_noise, fixed_window_mask, random_window_mask
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

    ``keep`` is a ``(min, max)`` range to draw windows from, or a fixed fraction per axis with a
    per-sample fixed seed.
    """

    spec: RadarSpec
    observability: str = "partial"  # "full": every cell observed
    keep: float | tuple[float, float] = 0.3
    noise_db: NoiseLevel = None
    mask_seed: int = 0

    def __post_init__(self):
        if self.observability not in ("full", "partial"):
            raise UserInputError(f"observability: expected 'full' or 'partial', got {self.observability!r}")

    def mask(self, n_aspect: int, n_roll: int, rng: np.random.Generator, index: int) -> np.ndarray:
        """Observed cells ``[A, R]``: one contiguous window per axis (roll wraps around)."""
        if self.observability == "full":
            return np.ones((n_aspect, n_roll), dtype=bool)
        if isinstance(self.keep, (int, float)):
            return fixed_window_mask(n_aspect, n_roll, float(self.keep), self.mask_seed + index)
        low, high = map(float, self.keep)
        return random_window_mask(n_aspect, n_roll, low, high, rng)

    def __call__(self, response: np.ndarray, rng: np.random.Generator, index: int) -> tuple[np.ndarray, np.ndarray]:
        """``(radar float32 [A, R, F], mask bool [A, R])`` from a complex ``response [A, R, F]``."""
        level = draw_noise_level(self.noise_db, rng)
        if level is not None:
            response = add_noise(response, level, rng)
        db = self.spec.to_db(response)
        mask = self.mask(response.shape[0], response.shape[1], rng, index)
        return self.spec.normalise(db, mask), mask
