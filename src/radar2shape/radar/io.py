"""The response file: one .npz with ``response`` complex64 [A, R, F] and its three axes.

Writes are atomic (``radar2shape.atomic``: temporary file in the target folder, then a rename) so
a reader never sees half a file; reads check every field and say which one is wrong.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from radar2shape.atomic import atomic_open
from radar2shape.errors import UserInputError

AXES = ("aspect_rad", "roll_rad", "freq_hz")


@dataclass(frozen=True, eq=False)
class RadarResponse:
    """A complex response with its axes (radians, hertz); ``size_m`` when it was recorded."""

    response: np.ndarray
    aspect_rad: np.ndarray
    roll_rad: np.ndarray
    freq_hz: np.ndarray
    size_m: float | None = None


def _validated(name: str, response, aspect_rad, roll_rad, freq_hz) -> tuple[np.ndarray, ...]:
    response = np.asarray(response)
    axes = [np.asarray(a) for a in (aspect_rad, roll_rad, freq_hz)]
    if not np.iscomplexobj(response) or response.ndim != 3:
        raise UserInputError(f"{name}: 'response' must be complex [A, R, F], got {response.dtype} {response.shape}")
    if 0 in response.shape:
        raise UserInputError(f"{name}: 'response' has an empty axis, shape {response.shape} "
                             "(expected at least one aspect, roll and frequency)")
    for field, axis, size in zip(AXES, axes, response.shape):
        if axis.ndim != 1 or len(axis) != size or not np.issubdtype(axis.dtype, np.number):
            raise UserInputError(f"{name}: '{field}' must be a 1-D array of {size} numbers "
                                 f"to match response {response.shape}, got {axis.dtype} {axis.shape}")
        if not np.isfinite(axis).all():
            raise UserInputError(f"{name}: '{field}' contains NaN or infinite values")
    if not np.isfinite(response).all():
        raise UserInputError(f"{name}: 'response' contains NaN or infinite values")
    return (response.astype(np.complex64), *(a.astype(np.float64) for a in axes))


def save_response(path: str | Path, response, aspect_rad, roll_rad, freq_hz, size_m: float | None = None) -> Path:
    """Write the .npz atomically; returns the path written."""
    path = Path(path)
    arrays = dict(zip(("response",) + AXES, _validated(str(path), response, aspect_rad, roll_rad, freq_hz)))
    if size_m is not None:
        arrays["size_m"] = np.float64(size_m)
    with atomic_open(path, "wb") as handle:
        np.savez(handle, **arrays)
    return path


def read_npz_fields(path: Path, what: str) -> dict[str, np.ndarray]:
    """All named arrays of an ``.npz`` (no pickles); one-line errors for a missing or unreadable file."""
    if not path.is_file():
        raise UserInputError(f"{path}: {what} not found")
    try:
        data = np.load(path, allow_pickle=False)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise ValueError(f"holds a single {type(data).__name__}, not named arrays")
        with data:
            return {f: data[f] for f in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as err:
        raise UserInputError(f"{path}: not a readable .npz {what} ({err})") from err


def load_response(path: str | Path) -> RadarResponse:
    """Read and check a response file written by ``save_response`` (or by hand)."""
    path = Path(path)
    fields = read_npz_fields(path, "response file")
    missing = [f for f in ("response",) + AXES if f not in fields]
    if missing:
        raise UserInputError(f"{path}: missing field(s) {missing} (expected response, {', '.join(AXES)})")
    response, aspect, roll, freq = _validated(str(path), *(fields[f] for f in ("response",) + AXES))
    size = fields.get("size_m")
    return RadarResponse(response, aspect, roll, freq, None if size is None else float(size))
