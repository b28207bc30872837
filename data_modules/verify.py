"""Check every record of a built dataset against its manifest, and rebuild exactly the bad ones.

``radar2shape build-data --verify DIR`` reads each record the manifest lists in full (which also
checks the zip CRCs) and checks its keys, dtypes and shapes against the build config, that every
float is finite, and that its id, split, label, class and radar axes agree with the manifest.
``--repair --config C`` rebuilds the bad records from the same config: records are pure
functions of (config, task) written byte-deterministically, so a repaired record is byte-equal
to the original build's. A manifest that cannot be read is itself a problem; the records are
then planned from ``build_config.json`` and repair rewrites the manifest.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from data_modules.config import BuildConfig, config_from_dict
from data_modules.manifest import MANIFEST, read_manifest, write_manifest
from data_modules.records import RECORD_KEYS, read_record, record_path, skip_path, write_record
from radar2shape.errors import BadRecordError, UserInputError

CONFIG_FILE = "build_config.json"  # as data_modules.build (not imported: the build pulls in torch)


@dataclass(frozen=True)
class Problem:
    """One bad file: a record (``split``, ``record_id`` set) or the manifest (both None)."""

    path: Path
    reason: str
    split: str | None = None
    record_id: str | None = None


@dataclass
class Verification:
    """What ``verify_dataset`` found: records checked, problems, and where the list came from."""

    root: Path
    checked: int
    problems: list[Problem]
    config: BuildConfig
    manifest: dict | None


def _build_config(root: Path) -> BuildConfig:
    """The dataset's build config: ``build_config.json``, else the manifest's copy."""
    path = root / CONFIG_FILE
    if path.is_file():
        try:
            return config_from_dict(json.loads(path.read_text()))
        except (ValueError, UnicodeDecodeError):
            pass
    try:
        return config_from_dict(read_manifest(root)["config"])
    except (UserInputError, KeyError):
        pass
    if not root.is_dir():
        raise UserInputError(f"--verify: dataset folder {root} not found")
    raise UserInputError(f"--verify: {root} holds no readable {CONFIG_FILE} or {MANIFEST}: not a dataset "
                         "folder of build-data (or both files are damaged: rebuild it)")


def _expected(config: BuildConfig, manifest: dict | None) -> dict[str, tuple[str, tuple]]:
    """key -> (dtype, shape with None for free sizes) of a record of this build."""
    from radar2shape.radar import RadarGrid

    grid = RadarGrid.from_config(config.radar)
    s = config.sampling
    expected = {
        "vertices": ("float32", (None, 3)), "faces": ("int32", (None, 3)),
        "surface_points": ("float32", (s.surface, 3)), "surface_normals": ("float32", (s.surface, 3)),
        "eval_points": ("float32", (s.eval, 3)),
        "sdf_points": ("float32", (s.sdf, 3)), "sdf_values": ("float32", (s.sdf,)),
        "occ_points": ("float16", (s.occ, 3)), "occ_inside": ("bool", (s.occ,)),
        "radar": ("complex64", grid.shape),
        "aspect_rad": ("float64", (grid.shape[0],)), "roll_rad": ("float64", (grid.shape[1],)),
        "freq_hz": ("float64", (grid.shape[2],)), "size_m": ("float64", ()),
        "label": ("int64", ()), "class_name": ("str", ()), "record_id": ("str", ()), "split": ("str", ()),
        "provenance": ("str", ()),
    }
    if config.make_family().roll_symmetric:
        points = (manifest or {}).get("profile_points")
        expected["profile"] = ("float32", (points, 2))
    return expected


def _shape_ok(shape: tuple, pattern: tuple) -> bool:
    return len(shape) == len(pattern) and all(p is None or p == n for n, p in zip(shape, pattern))


def check_record(path: Path, split: str, record_id: str, label: int | None, classes: list[str] | None,
                 expected: dict, radar: dict | None) -> str | None:
    """The first thing wrong with one record, or None when it is good."""
    try:
        record = read_record(path)
    except BadRecordError as err:
        cause = err.__cause__
        return "missing" if cause is None else " ".join(f"{type(cause).__name__}: {cause}".split())
    missing = [key for key in expected if key not in record]
    if missing:
        return f"missing keys {missing}"
    for key, (dtype, pattern) in expected.items():
        value = record[key]
        if dtype == "str":
            if not isinstance(value, str):
                return f"{key}: expected text, got {getattr(value, 'dtype', type(value).__name__)}"
            continue
        if str(value.dtype) != dtype or not _shape_ok(value.shape, pattern):
            want = "[" + ", ".join("N" if p is None else str(p) for p in pattern) + "]"
            return f"{key}: expected {dtype} {want}, got {value.dtype} {list(value.shape)}"
        if value.dtype.kind in "fc" and not np.isfinite(value).all():
            return f"{key}: {int((~np.isfinite(value)).sum())} non-finite values"
    faces, vertices = record["faces"], record["vertices"]
    if len(faces) == 0 or faces.min() < 0 or faces.max() >= len(vertices):
        return f"faces: indices outside the {len(vertices)} vertices (or no faces)"
    if record["record_id"] != record_id or record["split"] != split:
        return f"holds record {record['split']}/{record['record_id']}, not {split}/{record_id}"
    if label is not None and int(record["label"]) != label:
        return f"label {int(record['label'])}, the manifest says {label}"
    if classes is not None and not (0 <= label < len(classes) and record["class_name"] == classes[label]):
        return f"class {record['class_name']!r} does not match the manifest's class of label {label}"
    for key in ("aspect_rad", "roll_rad", "freq_hz"):
        if radar is not None and not np.array_equal(record[key], np.asarray(radar[key], dtype=np.float64)):
            return f"{key}: differs from the manifest's radar axes"
    if radar is not None and float(record["size_m"]) != float(radar["size_m"]):
        return f"size_m {float(record['size_m'])}, the manifest says {radar['size_m']}"
    try:
        json.loads(record["provenance"])
    except ValueError:
        return "provenance: not JSON"
    return None


def _planned(root: Path, config: BuildConfig) -> list[tuple[str, str, int]]:
    """(split, id, label) of every planned task without a skip marker (when the manifest is unreadable)."""
    tasks = config.make_family().plan(config.num, config.splits, config.seed)
    return [(t.split, t.record_id, t.label) for t in tasks if not skip_path(root, t.split, t.record_id).exists()]


def verify_dataset(root: str | Path) -> Verification:
    """Check every record listed by the manifest (or planned, without one); nothing is written."""
    root = Path(root)
    config = _build_config(root)
    problems: list[Problem] = []
    try:
        manifest = read_manifest(root)
    except UserInputError as err:
        manifest = None
        problems.append(Problem(root / MANIFEST, str(err).split(": ", 1)[-1]))
    if manifest is not None:
        entries = [(split, rid, manifest["labels"][split][i])
                   for split, ids in manifest["splits"].items() for i, rid in enumerate(ids)]
        classes, radar = manifest["classes"], manifest["radar"]
    else:
        entries, classes, radar = _planned(root, config), None, None
    expected = _expected(config, manifest)
    if "profile" in expected and expected["profile"][1][0] is None:
        expected["profile"] = ("float32", (None, 2))
    for split, record_id, label in entries:
        path = record_path(root, split, record_id)
        reason = check_record(path, split, record_id, label, classes, expected, radar)
        if reason is not None:
            problems.append(Problem(path, reason, split, record_id))
    return Verification(root, len(entries), problems, config, manifest)


def repair_dataset(verification: Verification, config: BuildConfig) -> list[Path]:
    """Rebuild the bad records of ``verification`` from ``config`` (which must be the dataset's),
    then rewrite the manifest when it was bad; returns the files written."""
    from data_modules.record_builder import RecordBuilder

    root = verification.root
    theirs, ours = verification.config.to_dict(), config.to_dict()
    theirs.setdefault("simulator", {})
    if theirs != ours:
        changed = sorted(k for k in set(theirs) | set(ours) if theirs.get(k) != ours.get(k))
        raise UserInputError(f"--config: differs from the config {root} was built with (changed: "
                             f"{', '.join(changed)}); repair needs the same config")
    family = config.make_family()
    tasks = family.plan(config.num, config.splits, config.seed)
    by_id = {(t.split, t.record_id): t for t in tasks}
    bad = [p for p in verification.problems if p.record_id is not None]
    unknown = [p for p in bad if (p.split, p.record_id) not in by_id]
    if unknown:
        raise UserInputError(f"{unknown[0].path}: listed by the manifest but not planned by the config; "
                             "the manifest does not belong to this build (rebuild the dataset)")
    written: list[Path] = []
    builder = RecordBuilder(config) if bad else None
    for problem in bad:
        write_record(problem.path, builder.build(by_id[(problem.split, problem.record_id)]))
        written.append(problem.path)
    if any(p.record_id is None for p in verification.problems):
        write_manifest(root, config, family, tasks)
        written.append(root / MANIFEST)
    return written
