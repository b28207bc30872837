"""dB conversion and measurement noise on complex responses (docs/design.md section 2)."""

from __future__ import annotations

import numpy as np

from radar2shape.errors import UserInputError


def to_db(response: np.ndarray, floor_db: float = -100.0) -> np.ndarray:
    """20 log10 |S| in dBsm, clipped below at ``floor_db`` so empty cells stay finite."""
    magnitude = np.abs(np.asarray(response))
    floor = 10.0 ** (floor_db / 20.0)
    return 20.0 * np.log10(np.maximum(magnitude, floor))


def add_noise(response: np.ndarray, level_db: float, rng: np.random.Generator | int | None = None) -> np.ndarray:
    """``response`` plus circular complex Gaussian noise of absolute power 10^(level_db/10) m^2.

    E|n|^2 = 10^(level_db / 10), i.e. ``level_db`` is a noise floor in dBsm (the paper's
    -80/-60/-40 dB levels), not a signal-to-noise ratio. Real and imaginary parts each carry
    half the power. The result keeps the input's complex dtype.
    """
    response = np.asarray(response)
    if not np.iscomplexobj(response):
        raise UserInputError(f"response: expected a complex array, got {response.dtype}")
    if not np.isfinite(level_db):
        raise UserInputError(f"level_db: expected a finite number, got {level_db!r}")
    rng = np.random.default_rng(rng)
    sigma = np.sqrt(10.0 ** (level_db / 10.0) / 2.0)
    noise = rng.normal(0.0, sigma, size=response.shape) + 1j * rng.normal(0.0, sigma, size=response.shape)
    return (response + noise).astype(response.dtype)
