"""Measured monostatic radar: readers and resampling onto a model's radar grid (docs/measured.md).

Readers turn a file into a :class:`Measurement`, a dBsm array ``[A, R, F]`` on the file's own
sample axes with NaN where the file has no sample:

- :func:`read_austin`: Austin RCS Benchmark text files, four whitespace-separated columns
  ``frequency (Hz), theta (deg), phi (deg), RCS (dBsm)``; theta is our aspect, phi our roll
  (the same spherical convention, u = (sin t cos p, sin t sin p, cos t)); one or more files
  (e.g. one per frequency) make one measurement;
- :func:`read_csv`: the generic long format, a header naming ``aspect_deg``, ``freq_ghz``,
  optionally ``roll_deg`` (absent: an aspect-only response at roll 0), and the value as
  ``rcs_dbsm`` or as the complex field ``re, im`` (|S|^2 = RCS in m^2, time factor e^{jwt});
- :func:`read_npz`: the generic dense format, axes ``aspect_rad``, ``freq_hz``, optionally
  ``roll_rad``, and ``response`` (complex) or ``rcs_dbsm``, optionally ``observed`` (bool);
  the files ``radar2shape simulate`` writes are of this format.

Rows of a text file must be sorted (strictly increasing in its key columns, so a duplicated
angle is an error too) and finite; every violation is a ``UserInputError`` naming the file,
the column and the line. :func:`resample` puts a measurement on a model's grid: linear
interpolation of dB, unobserved cells masked (never zero-filled), a partly overlapping band
accepted down to ``min_overlap`` of the model's band, optional calibration offset and
electromagnetic size scaling.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from radar2shape.errors import UserInputError
from radar2shape.radar.io import read_npz_fields
from radar2shape.radar.signal import to_db

TWO_PI = 2.0 * np.pi
DEG = np.pi / 180.0
FORMATS = ("austin", "csv", "npz")
MIN_OVERLAP = 0.5  # default: the file's band must cover at least half of the model's band
MAX_GAP_STEPS = 2.0  # default: interpolate across source gaps of at most two model steps
READ_FLOOR_DB = -300.0  # complex inputs: |S| = 0 becomes -300 dBsm (the model's floor clips it later)


@dataclass(frozen=True, eq=False)
class Measurement:
    """A response on the file's own axes (radians, hertz): dBsm ``[A, R, F]``, NaN = not measured."""

    db: np.ndarray
    aspect_rad: np.ndarray
    roll_rad: np.ndarray
    freq_hz: np.ndarray
    source: str

    @property
    def observed(self) -> np.ndarray:
        return np.isfinite(self.db)

    @property
    def aspect_only(self) -> bool:
        """One roll angle: the response of a body of revolution seen along one meridian."""
        return len(self.roll_rad) == 1


# ---- text tables ---------------------------------------------------------------------------------
def _parse_rows(path: Path, lines: list[tuple[int, list[str]]], columns: list[str]) -> np.ndarray:
    """``[N, len(columns)]`` floats; a short row, a non-number or a NaN/inf names file, line and column."""
    out = np.empty((len(lines), len(columns)))
    for row, (line, fields) in enumerate(lines):
        if len(fields) < len(columns):
            raise UserInputError(f"{path}: line {line}: missing column '{columns[len(fields)]}' "
                                 f"(expected {len(columns)} values: {', '.join(columns)}, got {len(fields)})")
        for col, name in enumerate(columns):
            try:
                value = float(fields[col])
            except ValueError:
                raise UserInputError(f"{path}: line {line}, column '{name}': {fields[col]!r} is not a number") from None
            if not np.isfinite(value):
                raise UserInputError(f"{path}: line {line}, column '{name}': {fields[col]} (NaN or infinite)")
            out[row, col] = value
    return out


def _check_sorted(where: list[str], keys: np.ndarray, names: list[str]) -> None:
    """Rows strictly increasing in ``keys`` (lexicographic): names the line and column of the first fault.

    ``where[i]`` is "FILE: line N" of row i. Equal consecutive keys are a duplicated sample.
    """
    if len(keys) < 2:
        return
    diff = np.sign(np.diff(keys, axis=0))
    first = np.argmax(diff != 0, axis=1)  # the first key column that changes between two rows
    step = diff[np.arange(len(diff)), first]
    bad = np.flatnonzero(step <= 0)
    if len(bad) == 0:
        return
    i = int(bad[0])
    key = ", ".join(f"{n} {v:g}" for n, v in zip(names, keys[i + 1]))
    before = where[i]
    if before.rsplit(": line", 1)[0] == where[i + 1].rsplit(": line", 1)[0]:
        before = "line" + before.rsplit(": line", 1)[1]  # same file: the line number is enough
    if step[i] == 0:
        raise UserInputError(f"{where[i + 1]}: duplicated sample ({key}) already on {before}; "
                             f"each ({', '.join(names)}) may appear once")
    col = names[first[i]]
    raise UserInputError(f"{where[i + 1]}, column '{col}': {keys[i + 1, first[i]]:g} comes after "
                         f"{keys[i, first[i]]:g} on {before}; rows must be sorted "
                         f"by {', then '.join(names)} (ascending)")


def _text_lines(path: Path) -> list[tuple[int, str]]:
    """(1-based line number, stripped text) of the non-empty, non-comment lines."""
    if not path.is_file():
        raise UserInputError(f"{path}: measured file not found")
    try:
        text = path.read_text(encoding="utf-8-sig")  # a spreadsheet export may start with a BOM
    except (OSError, UnicodeDecodeError) as err:
        raise UserInputError(f"{path}: cannot read ({err})") from err
    lines = [(n, s.strip()) for n, s in enumerate(text.splitlines(), start=1)]
    lines = [(n, s) for n, s in lines if s and not s.startswith("#")]
    if not lines:
        raise UserInputError(f"{path}: no data rows")
    return lines


def _grid_from_rows(source: str, aspect: np.ndarray, roll: np.ndarray, freq: np.ndarray,
                    db: np.ndarray) -> Measurement:
    """Scattered, unique samples -> a dense ``[A, R, F]`` array on their distinct values (NaN elsewhere)."""
    axes, index = zip(*(np.unique(v, return_inverse=True) for v in (aspect, roll, freq)))
    dense = np.full(tuple(len(a) for a in axes), np.nan)
    dense[index] = db
    return Measurement(dense, axes[0] * DEG, axes[1] * DEG, axes[2], source)


AUSTIN_COLUMNS = ["frequency_hz", "theta_deg", "phi_deg", "rcs_dbsm"]


def read_austin(paths: str | Path | Sequence[str | Path]) -> Measurement:
    """One or more Austin RCS Benchmark files (rows sorted by frequency, theta, phi) as one measurement."""
    paths = [Path(p) for p in ([paths] if isinstance(paths, (str, Path)) else paths)]
    if not paths:
        raise UserInputError("read_austin: no files given")
    if len(set(paths)) < len(paths):
        raise UserInputError(f"{next(p for p in paths if paths.count(p) > 1)}: given twice")
    tables, where = [], []
    for path in paths:
        lines = _text_lines(path)
        rows = _parse_rows(path, [(n, s.split()) for n, s in lines], AUSTIN_COLUMNS)
        here = [f"{path}: line {n}" for n, _ in lines]
        _check_sorted(here, rows[:, :3], AUSTIN_COLUMNS[:3])
        tables.append(rows)
        where += here
    rows = np.concatenate(tables)
    if len(paths) > 1:  # the same sample in two files
        order = np.lexsort(rows[:, 2::-1].T)
        _check_sorted([where[i] for i in order], rows[order, :3], AUSTIN_COLUMNS[:3])
    _check_angles(where, rows[:, 1], "theta_deg")
    freq, theta, phi, db = rows.T
    source = ", ".join(str(p) for p in paths)
    return _grid_from_rows(source, theta, phi, freq, db)


def _check_angles(where: list[str], aspect_deg: np.ndarray, name: str) -> None:
    bad = np.flatnonzero((aspect_deg < -1e-9) | (aspect_deg > 180 + 1e-9))
    if len(bad):
        raise UserInputError(f"{where[bad[0]]}, column '{name}': {aspect_deg[bad[0]]:g} is outside 0..180 deg")


CSV_KEYS = ["aspect_deg", "roll_deg", "freq_ghz"]


def read_csv(path: str | Path) -> Measurement:
    """The generic CSV (header ``aspect_deg[,roll_deg],freq_ghz`` and ``rcs_dbsm`` or ``re,im``)."""
    path = Path(path)
    lines = _text_lines(path)
    header = [h.strip().lower() for h in lines[0][1].split(",")]
    for name in ("aspect_deg", "freq_ghz"):
        if name not in header:
            raise UserInputError(f"{path}: line {lines[0][0]} (header): missing column '{name}' "
                                 f"(have {header}; expected aspect_deg[, roll_deg], freq_ghz and rcs_dbsm or re, im)")
    complex_value = "rcs_dbsm" not in header
    if complex_value and not {"re", "im"} <= set(header):
        missing = "rcs_dbsm" if not {"re", "im"} & set(header) else ("im" if "re" in header else "re")
        raise UserInputError(f"{path}: line {lines[0][0]} (header): missing column '{missing}' "
                             "(the value is rcs_dbsm, or the complex field as re, im)")
    names = [n for n in CSV_KEYS if n in header] + (["re", "im"] if complex_value else ["rcs_dbsm"])
    picked = [header.index(n) for n in names]
    split = [(n, s.split(",")) for n, s in lines[1:]]
    if not split:
        raise UserInputError(f"{path}: header only, no data rows")
    width = max(picked) + 1
    for n, fields in split:
        if len(fields) < width:
            missing = header[len(fields)] if len(fields) < len(header) else header[-1]
            raise UserInputError(f"{path}: line {n}: missing column '{missing}' "
                                 f"(the header has {len(header)} columns, the row {len(fields)})")
    rows = _parse_rows(path, [(n, [f[i] for i in picked]) for n, f in split], names)
    where = [f"{path}: line {n}" for n, _ in split]
    has_roll = "roll_deg" in names
    keys = rows[:, : 3 if has_roll else 2]
    _check_sorted(where, keys, [n for n in CSV_KEYS if n in names])
    _check_angles(where, rows[:, 0], "aspect_deg")
    bad = np.flatnonzero(rows[:, names.index("freq_ghz")] <= 0)
    if len(bad):
        raise UserInputError(f"{where[bad[0]]}, column 'freq_ghz': frequencies must be positive")
    value = rows[:, -2] + 1j * rows[:, -1] if complex_value else rows[:, -1]
    db = to_db(value, READ_FLOOR_DB) if complex_value else value
    roll = rows[:, 1] if has_roll else np.zeros(len(rows))
    return _grid_from_rows(str(path), rows[:, 0], roll, rows[:, names.index("freq_ghz")] * 1e9, db)


# ---- npz -------------------------------------------------------------------------------------------
def _npz_axis(path: Path, fields: dict, name: str, size: int, unit_range: tuple[float, float] | None) -> np.ndarray:
    axis = np.asarray(fields[name])
    if axis.ndim != 1 or len(axis) != size or not np.issubdtype(axis.dtype, np.number) or np.iscomplexobj(axis):
        raise UserInputError(f"{path}: '{name}' must be a 1-D array of {size} real numbers, got {axis.dtype} {axis.shape}")
    axis = axis.astype(np.float64)
    bad = np.flatnonzero(~np.isfinite(axis))
    if len(bad):
        raise UserInputError(f"{path}: '{name}'[{bad[0]}] is NaN or infinite")
    bad = np.flatnonzero(np.diff(axis) <= 0)
    if len(bad):
        i = int(bad[0]) + 1
        kind = "duplicates" if axis[i] == axis[i - 1] else "is below"
        raise UserInputError(f"{path}: '{name}'[{i}] = {axis[i]:g} {kind} '{name}'[{i - 1}]; axes must be strictly increasing")
    if unit_range is not None and (axis.min() < unit_range[0] - 1e-9 or axis.max() > unit_range[1] + 1e-9):
        i = int(np.argmax((axis < unit_range[0] - 1e-9) | (axis > unit_range[1] + 1e-9)))
        raise UserInputError(f"{path}: '{name}'[{i}] = {axis[i]:g} is outside [{unit_range[0]:g}, {unit_range[1]:g}]")
    return axis


def read_npz(path: str | Path) -> Measurement:
    """The generic NPZ: ``aspect_rad``, ``freq_hz``, [``roll_rad``], ``response`` or ``rcs_dbsm``, [``observed``]."""
    path = Path(path)
    fields = read_npz_fields(path, "measured file")
    value_name = "response" if "response" in fields else "rcs_dbsm"
    missing = [f for f in ("aspect_rad", "freq_hz", value_name) if f not in fields]
    if missing:
        raise UserInputError(f"{path}: missing array(s) {missing} (expected aspect_rad, freq_hz, [roll_rad], "
                             "and response (complex) or rcs_dbsm)")
    value = np.asarray(fields[value_name])
    has_roll = "roll_rad" in fields
    if value.ndim != (3 if has_roll else 2):
        raise UserInputError(f"{path}: '{value_name}' must be [A, R, F] with roll_rad or [A, F] without, got {value.shape}")
    if 0 in value.shape:
        raise UserInputError(f"{path}: '{value_name}' has an empty axis, shape {value.shape} "
                             "(expected at least one aspect, roll and frequency)")
    if (value_name == "response") != np.iscomplexobj(value):
        raise UserInputError(f"{path}: 'response' must be complex and 'rcs_dbsm' real, got {value_name} {value.dtype}")
    if not has_roll:
        value = value[:, None, :]
    aspect = _npz_axis(path, fields, "aspect_rad", value.shape[0], (0.0, np.pi))
    roll = _npz_axis(path, fields, "roll_rad", value.shape[1], None) if has_roll else np.zeros(1)
    freq = _npz_axis(path, fields, "freq_hz", value.shape[2], (1e-300, np.inf))
    observed = np.ones(value.shape, dtype=bool)
    if "observed" in fields:
        observed = np.asarray(fields["observed"])
        if observed.dtype != bool or observed.shape != np.asarray(fields[value_name]).shape:
            raise UserInputError(f"{path}: 'observed' must be bool with the shape of '{value_name}' "
                                 f"{np.asarray(fields[value_name]).shape}, got {observed.dtype} {observed.shape}")
        observed = observed if has_roll else observed[:, None, :]
    bad = np.argwhere(observed & ~np.isfinite(value))
    if len(bad):
        index = tuple(int(i) for i in bad[0]) if has_roll else (int(bad[0][0]), int(bad[0][2]))
        raise UserInputError(f"{path}: '{value_name}'{list(index)} is NaN or infinite (mark unmeasured cells with 'observed')")
    db = to_db(value, READ_FLOOR_DB) if value_name == "response" else value.astype(np.float64)
    return Measurement(np.where(observed, db, np.nan), aspect, roll, freq, str(path))


def guess_format(path: str | Path) -> str:
    """``austin`` for .txt, ``csv`` for .csv, ``npz`` for .npz; anything else must be named."""
    suffix = Path(path).suffix.lower()
    formats = {".txt": "austin", ".csv": "csv", ".npz": "npz"}
    if suffix not in formats:
        raise UserInputError(f"{path}: cannot tell the format from the suffix {suffix!r}; give --format {'|'.join(FORMATS)}")
    return formats[suffix]


def read_measured(paths: str | Path | Sequence[str | Path], fmt: str | None = None) -> Measurement:
    """Read one file (or several Austin files) in format ``fmt`` (default: from the suffix)."""
    paths = [Path(p) for p in ([paths] if isinstance(paths, (str, Path)) else paths)]
    fmt = fmt or guess_format(paths[0])
    if fmt not in FORMATS:
        raise UserInputError(f"--format: expected one of {FORMATS}, got {fmt!r}")
    if fmt == "austin":
        return read_austin(paths)
    if len(paths) != 1:
        raise UserInputError(f"--format {fmt} reads one file, got {len(paths)} (only Austin files combine)")
    return (read_csv if fmt == "csv" else read_npz)(paths[0])


# ---- resampling -----------------------------------------------------------------------------------
def full_circle(roll: np.ndarray) -> bool:
    """True when the roll samples go round the circle: no gap (the seam included) above 1.5x the median gap."""
    angles = np.unique(np.mod(np.asarray(roll, float), TWO_PI))
    if len(angles) < 3:
        return False
    gaps = np.diff(np.append(angles, angles[0] + TWO_PI))
    return bool(gaps.max() <= 1.5 * np.median(gaps))


def _step(target: np.ndarray, periodic: bool) -> float:
    if len(target) < 2:
        return TWO_PI if periodic else np.inf
    return float(np.median(np.diff(np.sort(target))))


def _weights(xs: np.ndarray, t: np.ndarray, max_gap: float, snap: float) -> tuple[np.ndarray, ...]:
    """(lo, hi, w, ok) so that value(t) = y[lo] (1 - w) + y[hi] w where ok.

    Linear between the two bracketing samples when they are at most ``max_gap`` apart (or t hits
    a sample); otherwise the nearest sample when it lies within ``snap``; otherwise not ok.
    """
    tol = 1e-9 * max(1.0, float(np.abs(xs).max()))
    nearest = np.abs(xs[None, :] - t[:, None]).argmin(axis=1)
    near_ok = np.abs(xs[nearest] - t) <= snap + tol
    if len(xs) == 1:
        zeros = np.zeros(len(t), dtype=int)
        return zeros, zeros, np.zeros(len(t)), near_ok
    hi = np.clip(np.searchsorted(xs, t, side="left"), 1, len(xs) - 1)
    lo = hi - 1
    w = np.clip((t - xs[lo]) / (xs[hi] - xs[lo]), 0.0, 1.0)
    inside = (t >= xs[0] - tol) & (t <= xs[-1] + tol)
    exact = np.abs(xs[nearest] - t) <= tol
    linear = inside & ((xs[hi] - xs[lo] <= max_gap + tol) | exact)
    lo, hi, w = np.where(linear, lo, nearest), np.where(linear, hi, nearest), np.where(linear, w, 0.0)
    return lo, hi, w, linear | near_ok


def interpolate_axis(values: np.ndarray, source: np.ndarray, target: np.ndarray, axis: int,
                     periodic: bool = False, max_gap_steps: float = MAX_GAP_STEPS) -> np.ndarray:
    """Linear interpolation along ``axis`` that skips missing (NaN) samples and never invents data.

    A target value gets the linear blend of its two bracketing observed samples when they are at
    most ``max_gap_steps`` target steps apart, else the nearest observed sample within half a
    target step, else NaN. ``periodic``: angles on a circle covered by the source (roll).
    """
    source, target = np.asarray(source, float), np.asarray(target, float)
    moved = np.moveaxis(np.asarray(values, float), axis, -1)
    if periodic:  # one period of padding on both sides; 0 and 2 pi count as one sample
        source, first = np.unique(np.mod(source, TWO_PI), return_index=True)
        moved = moved[..., first]
        source = np.concatenate([source - TWO_PI, source, source + TWO_PI])
        moved = np.concatenate([moved, moved, moved], axis=-1)
        target = np.mod(target, TWO_PI)
    step = _step(target, periodic)
    lines = moved.reshape(-1, moved.shape[-1])
    out = np.full((len(lines), len(target)), np.nan)
    valid = np.isfinite(lines)
    patterns, group = np.unique(valid, axis=0, return_inverse=True)
    for k, pattern in enumerate(patterns):
        if not pattern.any():
            continue
        rows = np.flatnonzero(group.ravel() == k)
        ys = lines[np.ix_(rows, np.flatnonzero(pattern))]
        lo, hi, w, ok = _weights(source[pattern], target, max_gap_steps * step, step / 2)
        blend = ys[:, lo] * (1 - w) + ys[:, hi] * w
        out[rows] = np.where(ok, blend, np.nan)
    return np.moveaxis(out.reshape(*moved.shape[:-1], len(target)), -1, axis)


@dataclass(frozen=True, eq=False)
class GridInput:
    """A measurement on a model's grid: dBsm ``[A, R, F]`` (NaN where masked) and what was observed.

    ``mask [A, R]`` is True where every frequency the file covers has a value; ``freq_mask [F]``
    marks the model frequencies inside the file's band (the others are NaN); ``overlap`` is the
    covered fraction of the model's band. The model's ``RadarSpec.normalise(db, mask)`` turns it
    into the network input, as in training.
    """

    db: np.ndarray
    mask: np.ndarray
    freq_mask: np.ndarray
    overlap: float


def band_overlap(freq_hz: np.ndarray, target_hz: np.ndarray) -> float:
    """Fraction of the target band [min, max] that the source band covers (1 or 0 for one frequency)."""
    lo, hi = float(np.min(target_hz)), float(np.max(target_hz))
    src_lo, src_hi = float(np.min(freq_hz)), float(np.max(freq_hz))
    if hi <= lo:
        return float(src_lo - 1e-9 * lo <= lo <= src_hi + 1e-9 * hi)
    return max(0.0, min(hi, src_hi) - max(lo, src_lo)) / (hi - lo)


def resample(measurement: Measurement, aspect_rad, roll_rad, freq_hz, *, floor_db: float = -100.0,
             calibration_db: float = 0.0, size_m: float | None = None, model_size_m: float = 1.0,
             min_overlap: float = MIN_OVERLAP, roll_symmetric: bool = False,
             max_gap_steps: float = MAX_GAP_STEPS) -> GridInput:
    """The measurement on the model's axes (see the module docstring and docs/measured.md).

    ``calibration_db`` is added to every value. ``size_m`` (the measured object's longest side)
    scales to the model's ``model_size_m`` by electromagnetic similarity: frequencies times
    ``size_m / model_size_m``, RCS minus ``20 log10(size_m / model_size_m)`` dB. With
    ``roll_symmetric`` an aspect-only measurement is repeated along every model roll.
    """
    m = measurement
    aspect, roll, freq = (np.asarray(a, float) for a in (aspect_rad, roll_rad, freq_hz))
    db, source_freq = m.db + float(calibration_db), m.freq_hz
    if size_m is not None:
        if not np.isfinite(size_m) or size_m <= 0:
            raise UserInputError(f"--size-m: expected a positive number of metres, got {size_m}")
        scale = size_m / model_size_m
        db, source_freq = db - 20.0 * np.log10(scale), source_freq * scale
    overlap = band_overlap(source_freq, freq)
    if overlap < min_overlap:
        raise UserInputError(
            f"{m.source}: the frequency band {source_freq.min() / 1e9:.6g}-{source_freq.max() / 1e9:.6g} GHz"
            f"{' (after size scaling)' if size_m is not None else ''} covers {100 * overlap:.0f} % of the model's "
            f"{freq.min() / 1e9:.6g}-{freq.max() / 1e9:.6g} GHz; at least {100 * min_overlap:.0f} % is needed")
    if roll_symmetric:
        if not m.aspect_only:
            raise UserInputError(f"{m.source}: --roll-symmetric expects an aspect-only response (one roll angle), "
                                 f"got {len(m.roll_rad)} roll angles")
        db = np.repeat(db, len(roll), axis=1)
        source_roll = roll
    elif m.aspect_only and len(roll) > 1:
        raise UserInputError(f"{m.source}: one roll angle but the model needs {len(roll)}; "
                             "for a roll-symmetric object add --roll-symmetric (repeats it along roll)")
    else:
        source_roll = m.roll_rad
    periodic = full_circle(source_roll)
    if not periodic and len(source_roll) > 1:  # an arc of roll: model rolls as angles from its start
        start = source_roll.min() - 0.5 * _step(roll, True)  # (e.g. a file's -30..30 deg covers 337.5 deg)
        roll = start + np.mod(roll - start, TWO_PI)
    db = interpolate_axis(db, source_freq, freq, 2, max_gap_steps=max_gap_steps)
    db = interpolate_axis(db, m.aspect_rad, aspect, 0, max_gap_steps=max_gap_steps)
    db = interpolate_axis(db, source_roll, roll, 1, periodic=periodic, max_gap_steps=max_gap_steps)
    db = np.maximum(db, floor_db)  # NaN stays NaN
    freq_mask = np.isfinite(db).any(axis=(0, 1))
    mask = np.isfinite(db[..., freq_mask]).all(axis=-1) if freq_mask.any() else np.zeros(db.shape[:2], bool)
    if not mask.any():
        raise UserInputError(f"{m.source}: no cell of the model's grid is covered (aspects "
                             f"{np.degrees(m.aspect_rad.min()):.4g}-{np.degrees(m.aspect_rad.max()):.4g} deg, "
                             f"{len(m.aspect_rad)} samples; the model's step is {np.degrees(_step(aspect, False)):.4g} deg)")
    db[~mask] = np.nan
    return GridInput(db, mask, freq_mask, overlap)


def write_csv(path: str | Path, aspect_deg, freq_ghz, rcs_dbsm, roll_deg=None) -> Path:
    """Write rows in the generic CSV format (sorted by aspect, roll, frequency; dB with 6 decimals)."""
    columns = [np.asarray(aspect_deg, float)] + ([] if roll_deg is None else [np.asarray(roll_deg, float)])
    columns += [np.asarray(freq_ghz, float), np.asarray(rcs_dbsm, float)]
    header = ["aspect_deg"] + ([] if roll_deg is None else ["roll_deg"]) + ["freq_ghz", "rcs_dbsm"]
    order = np.lexsort(columns[-2::-1])
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = "\n".join(",".join(f"{c[i]:.6f}" if k == len(columns) - 1 else f"{c[i]:.9g}" for k, c in enumerate(columns))
                     for i in order)
    path.write_text(",".join(header) + "\n" + rows + "\n")
    return path
