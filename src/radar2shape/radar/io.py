"""The response file: one .npz with ``response`` complex64 [A, R, F] and its three axes.

A ``polarization`` key names the channel ("VV", "HH", "HV" or "VH": first letter transmit,
second receive, V = theta-hat, H = phi-hat of the look direction); with several channels the
response is [A, R, F, P] and the key lists them in that order. Files without the key are VV,
the simulator's default.

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
DEFAULT_POLARIZATION = ("VV",)
POLARIZATIONS = ("VV", "HH", "HV", "VH")


@dataclass(frozen=True, eq=False)
class RadarResponse:
    """A complex response with its axes (radians, hertz); ``size_m`` when it was recorded."""

    response: np.ndarray
    aspect_rad: np.ndarray
    roll_rad: np.ndarray
    freq_hz: np.ndarray
    size_m: float | None = None
    polarization: tuple[str, ...] = DEFAULT_POLARIZATION  # one name for [A, R, F], P names for [A, R, F, P]


def _polarization(name: str, polarization, response_ndim: int) -> tuple[str, ...]:
    """The channel names as a tuple, checked against the response's rank (3: one, 4: one per slice)."""
    names = (polarization,) if isinstance(polarization, str) else tuple(str(p) for p in np.atleast_1d(polarization))
    names = tuple(n.upper() for n in names)
    if not names or any(n not in POLARIZATIONS for n in names) or (response_ndim == 3 and len(names) != 1):
        raise UserInputError(f"{name}: 'polarization' must be one of {', '.join(POLARIZATIONS)} for a [A, R, F] "
                             f"response, or one per channel of [A, R, F, P], got {polarization!r}")
    return names


def _validated(name: str, response, aspect_rad, roll_rad, freq_hz, polarization=DEFAULT_POLARIZATION):
    response = np.asarray(response)
    axes = [np.asarray(a) for a in (aspect_rad, roll_rad, freq_hz)]
    if not np.iscomplexobj(response) or response.ndim not in (3, 4):
        raise UserInputError(f"{name}: 'response' must be complex [A, R, F] (or [A, R, F, P] with P "
                             f"polarisations), got {response.dtype} {response.shape}")
    names = _polarization(name, polarization, response.ndim)
    if response.ndim == 4 and response.shape[3] != len(names):
        raise UserInputError(f"{name}: 'polarization' names {len(names)} channel(s) but response {response.shape} "
                             f"has {response.shape[3]}")
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
    return (response.astype(np.complex64), *(a.astype(np.float64) for a in axes), names)


def save_response(path: str | Path, response, aspect_rad, roll_rad, freq_hz, size_m: float | None = None,
                  polarization=None) -> Path:
    """Write the .npz atomically; returns the path written.

    ``polarization`` (a name, or one per channel of a [A, R, F, P] response) is stored as the
    ``polarization`` key; None writes no key for a [A, R, F] response (read back as VV).
    """
    path = Path(path)
    given = DEFAULT_POLARIZATION if polarization is None else polarization
    *fields, names = _validated(str(path), response, aspect_rad, roll_rad, freq_hz, given)
    arrays = dict(zip(("response",) + AXES, fields))
    if polarization is not None or np.ndim(response) == 4:
        arrays["polarization"] = np.array(names)
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
    polarization = fields.get("polarization", np.array(DEFAULT_POLARIZATION))
    if not np.issubdtype(polarization.dtype, np.str_):
        raise UserInputError(f"{path}: 'polarization' must hold text (e.g. 'VV'), got {polarization.dtype}")
    response, aspect, roll, freq, names = _validated(str(path), *(fields[f] for f in ("response",) + AXES),
                                                     polarization.tolist())
    size = fields.get("size_m")
    return RadarResponse(response, aspect, roll, freq, None if size is None else float(size), names)
