"""dB conversion and measurement noise on complex responses (docs/design.md section 2)."""

from __future__ import annotations

import numpy as np

from radar2shape.errors import UserInputError


def to_db(response: np.ndarray, floor_db: float = -100.0) -> np.ndarray:
    """20 log10 |S| in dBsm, clipped below at ``floor_db`` so empty cells stay finite."""
    magnitude = np.abs(np.asarray(response))
    floor = 10.0 ** (floor_db / 20.0)
    return 20.0 * np.log10(np.maximum(magnitude, floor))


NOISE_REFERENCES = ("absolute", "peak")


def noise_power(response: np.ndarray, level_db: float, reference: str = "absolute") -> float:
    """E|n|^2 in m^2 for ``level_db``: absolute (dBsm) or relative to the response's peak |S|^2.

    The peak (not the mean power) is the reference because it is what a receiver's dynamic range
    is set against, and it does not depend on how much of the grid sits in shadow or low-return
    regions: a level of -30 dB buries every cell more than 30 dB under the target's strongest return.
    """
    if reference not in NOISE_REFERENCES:
        raise UserInputError(f"noise_reference: expected one of {', '.join(NOISE_REFERENCES)}, got {reference!r}")
    if not np.isfinite(level_db):
        raise UserInputError(f"level_db: expected a finite number, got {level_db!r}")
    scale = 10.0 ** (level_db / 10.0)
    if reference == "absolute":
        return scale
    return scale * float(np.max(np.abs(response) ** 2, initial=0.0))


def add_noise(response: np.ndarray, level_db: float, rng: np.random.Generator | int | None = None,
              reference: str = "absolute") -> np.ndarray:
    """``response`` plus circular complex Gaussian noise at ``level_db``.

    ``reference="absolute"``: E|n|^2 = 10^(level_db / 10) m^2, i.e. ``level_db`` is a noise floor in
    dBsm (the paper's -80/-60/-40 dB levels), not a signal-to-noise ratio. ``reference="peak"``:
    E|n|^2 = 10^(level_db / 10) max |S|^2 over the whole ``response`` (``level_db`` < 0: dB below the
    peak), so the same level bites equally on small and large targets. Real and imaginary parts
    each carry half the power. The result keeps the input's complex dtype.
    """
    response = np.asarray(response)
    if not np.iscomplexobj(response):
        raise UserInputError(f"response: expected a complex array, got {response.dtype}")
    power = noise_power(response, level_db, reference)
    rng = np.random.default_rng(rng)
    sigma = np.sqrt(power / 2.0)
    noise = rng.normal(0.0, sigma, size=response.shape) + 1j * rng.normal(0.0, sigma, size=response.shape)
    return (response + noise).astype(response.dtype)
