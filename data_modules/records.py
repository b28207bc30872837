"""The on-disk record format: one ``.npz`` per shape, written atomically.

Layout of a built dataset (see docs/data.md):
    <root>/manifest.json                 splits, classes, config, counts, skipped inputs, radar stats
    <root>/build_config.json             the effective build config (guards resumed builds)
    <root>/records/<split>/<id>.npz      one record (keys: RECORD_KEYS)
    <root>/records/<split>/<id>.skip.json   an input that was skipped, with the reason
A record exists under its final name only once it is complete (temp file + ``os.replace``), so
a killed build never leaves a half-written record, and resuming means "skip what exists".
Record files are byte-deterministic (fixed zip member times), so a rebuilt or repaired record
equals the original byte for byte. A record that cannot be read raises ``BadRecordError`` naming
the file and ``radar2shape build-data --verify``.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from radar2shape.atomic import atomic_open
from radar2shape.errors import BadRecordError

RECORD_KEYS = (
    "vertices", "faces",                      # normalised watertight mesh (float32, int32)
    "surface_points", "surface_normals",      # [Ns, 3] float32
    "eval_points",                            # [Ne, 3] float32
    "sdf_points", "sdf_values",               # [Nd, 3], [Nd] float32, negative inside
    "occ_points", "occ_inside",               # [No, 3] float16 (uniform positions), [No] bool
    "radar",                                  # complex64 [A, R, F], |S|^2 = RCS in m^2
    "aspect_rad", "roll_rad", "freq_hz", "size_m",
    "label", "class_name", "record_id", "split",
    "provenance",                             # JSON text
)  # plus "profile" [P, 2] float32 for roll-symmetric families


def record_path(root: str | Path, split: str, record_id: str) -> Path:
    return Path(root) / "records" / split / f"{record_id}.npz"


def skip_path(root: str | Path, split: str, record_id: str) -> Path:
    return Path(root) / "records" / split / f"{record_id}.skip.json"


def _atomic_write(path: Path, write) -> None:
    """Write via ``write(stream)`` through the project's one atomic writer (temp file, fsync, rename)."""
    with atomic_open(path, "wb") as stream:
        write(stream)


_ZIP_TIME = (1980, 1, 1, 0, 0, 0)  # fixed member time: equal arrays give equal files


def _write_npz(stream, arrays: dict[str, np.ndarray]) -> None:
    """``np.savez`` layout (stored ``<key>.npy`` members, zip64) without the wall-clock member times."""
    with zipfile.ZipFile(stream, "w", zipfile.ZIP_STORED, allowZip64=True) as archive:
        for key, value in arrays.items():
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_TIME)
            info.external_attr = 0o600 << 16
            with archive.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)


def write_record(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """Atomically write a record (uncompressed: the arrays are random floats, and loads stay lazy)."""
    _atomic_write(path, lambda stream: _write_npz(stream, arrays))


def write_json(path: Path, data: dict) -> None:
    """Atomically write ``data`` as indented, key-sorted JSON (stable bytes for equal content)."""
    text = json.dumps(data, indent=1, sort_keys=True) + "\n"
    _atomic_write(path, lambda stream: stream.write(text.encode()))


def verify_command(path: str | Path) -> str:
    """The command that checks the dataset holding the record ``path`` (``<root>/records/<split>/<id>.npz``)."""
    path = Path(path)
    root = path.parents[2] if len(path.parents) > 2 and path.parent.parent.name == "records" else path.parent
    return f"radar2shape build-data --verify {root}"


def read_record(path: str | Path, keys: tuple[str, ...] | list[str] | None = None) -> dict:
    """The arrays of one record (all, or only ``keys``); string scalars come back as ``str``.

    A truncated or corrupt file (an interrupted copy) is one ``BadRecordError`` line naming the
    file and the verify command, as is a missing one.
    """
    try:
        with np.load(path, allow_pickle=False) as data:
            names = data.files if keys is None else [k for k in keys if k in data.files]
            out = {name: data[name] for name in names}
    except FileNotFoundError:
        raise BadRecordError(f"{path}: dataset record missing; list every bad record with "
                             f"'{verify_command(path)}'") from None
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError, OSError, KeyError) as err:
        reason = " ".join(f"{type(err).__name__}: {err}".split())
        raise BadRecordError(f"{path}: damaged dataset record ({reason}); list every bad record with "
                             f"'{verify_command(path)}'") from err
    for name, value in out.items():
        if value.dtype.kind == "U":
            out[name] = str(value)
    return out


def remove_stale_temps(root: str | Path) -> int:
    """Delete temp files left by killed writers; call only when no writer is running."""
    stale = list((Path(root) / "records").glob("*/.*.tmp*"))
    for path in stale:
        path.unlink(missing_ok=True)
    return len(stale)
