"""The dataset manifest: which records exist, their classes and splits, and radar statistics.

Written once every task of the build has a record or a skip marker (by the last shard to
finish, or by ``build-data --finalize``), from what is on disk, so it is the same whichever
shard, worker or resumed run produced the records. :func:`dataset_radar_spec` turns a manifest
into the :class:`~radar2shape.radar.spec.RadarSpec` models train on and store.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from data_modules.config import BuildConfig
from data_modules.records import read_record, record_path, remove_stale_temps, skip_path, write_json
from radar2shape.errors import UserInputError
from radar2shape.geometry.families import SPLITS, Family, ShapeTask
from radar2shape.radar import to_db
from radar2shape.radar.spec import RadarSpec

FORMAT = "radar2shape-records/1"
MANIFEST = "manifest.json"


def radar_db_stats(paths: list[Path], floor_db: float, roll_index: int | None = None) -> dict:
    """Mean and std of the dB radar over records (all rolls, or one roll), in float64 sums."""
    total = total_sq = count = 0.0
    for path in paths:
        radar = read_record(path, ["radar"])["radar"]
        if roll_index is not None:
            radar = radar[:, roll_index]
        db = to_db(radar, floor_db).astype(np.float64)
        total, total_sq, count = total + db.sum(), total_sq + np.square(db).sum(), count + db.size
    if count == 0:
        raise UserInputError("radar statistics need at least one train record")
    mean = total / count
    return {"floor_db": floor_db, "mean": mean, "std": float(np.sqrt(max(total_sq / count - mean**2, 1e-12)))}


def missing_tasks(root: Path, tasks: list[ShapeTask]) -> list[ShapeTask]:
    """Tasks with neither a record nor a skip marker."""
    return [t for t in tasks if not record_path(root, t.split, t.record_id).exists()
            and not skip_path(root, t.split, t.record_id).exists()]


def write_manifest(root: Path, config: BuildConfig, family: Family, tasks: list[ShapeTask]) -> dict:
    """Collect records and skip markers of ``tasks`` into ``root/manifest.json``."""
    missing = missing_tasks(root, tasks)
    if missing:
        raise UserInputError(f"{root}: {len(missing)} of {len(tasks)} records are not built yet "
                             "(run the remaining shards, or build-data again to resume)")
    splits = {split: [] for split in SPLITS}
    labels = {split: [] for split in SPLITS}
    skipped = []
    for task in tasks:
        marker = skip_path(root, task.split, task.record_id)
        if marker.exists():
            skipped.append(json.loads(marker.read_text()))
            continue
        splits[task.split].append(task.record_id)
        labels[task.split].append(task.label)
    built = [(split, ids[0]) for split, ids in splits.items() if ids]
    if not built:
        reasons = "; ".join(f"{e['source']}: {e['reason']}" for e in skipped[:3])
        raise UserInputError(f"{root}: no input could be built ({len(skipped)} skipped, e.g. {reasons})")
    first = read_record(record_path(root, *built[0]), ["aspect_rad", "roll_rad", "freq_hz", "size_m", "profile"])
    train = [record_path(root, "train", rid) for rid in splits["train"]]
    manifest = {
        "format": FORMAT,
        "family": family.name,
        "roll_symmetric": family.roll_symmetric,
        "classes": list(family.class_names),
        "splits": splits,
        "labels": labels,
        "counts": {split: len(ids) for split, ids in splits.items()} | {"skipped": len(skipped)},
        "skipped": skipped,
        "radar": {key: np.atleast_1d(first[key]).tolist() for key in ("aspect_rad", "roll_rad", "freq_hz")}
        | {"size_m": float(first["size_m"])},
        "profile_points": int(first["profile"].shape[0]) if "profile" in first else None,
        "radar_stats": radar_db_stats(train, config.floor_db) if train else None,
        "config": config.to_dict(),
    }
    remove_stale_temps(root)
    write_json(root / MANIFEST, manifest)
    return manifest


def read_manifest(root: str | Path) -> dict:
    """The manifest of a built dataset, with a clear error when it is not there."""
    path = Path(root) / MANIFEST
    if not path.is_file():
        hint = "run `make data` or `radar2shape build-data --config conf/data/NAME.yaml --out DIR`"
        if Path(root).is_dir():
            raise UserInputError(f"{path} not found: the dataset build has not finished ({hint}; it resumes)")
        raise UserInputError(f"dataset folder {Path(root)} not found: {hint}")
    try:
        manifest = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as err:  # truncated or overwritten: rewritten by a resumed build
        raise UserInputError(f"{path}: not a readable manifest ({type(err).__name__}: {err}); run the same "
                             "build-data command again to rewrite it (it resumes), or --finalize") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        found = manifest.get("format") if isinstance(manifest, dict) else type(manifest).__name__
        raise UserInputError(f"{path}: unknown dataset format {found!r} (expected {FORMAT})")
    return manifest


def train_db_stats(root: str | Path, manifest: dict, floor_db: float) -> dict:
    """Train dB mean/std at ``floor_db``: the manifest's when its floor matches, else computed once and cached."""
    stored = manifest.get("radar_stats")
    if stored and stored["floor_db"] == floor_db:
        return stored
    cache = Path(root) / f"radar_stats_floor{floor_db:g}.json"
    if cache.is_file():
        return json.loads(cache.read_text())
    stats = radar_db_stats([record_path(Path(root), "train", rid) for rid in manifest["splits"]["train"]], floor_db)
    try:
        write_json(cache, stats)
    except OSError:  # read-only dataset folder: keep the statistics in memory only
        pass
    return stats


def dataset_radar_spec(root: str | Path, manifest: dict, floor_db: float, roll_symmetric: bool = False) -> RadarSpec:
    """The radar spec of a built dataset at ``floor_db`` (aspect-only at its first roll when ``roll_symmetric``)."""
    return RadarSpec.from_manifest(manifest["radar"], train_db_stats(root, manifest, floor_db), roll_symmetric)
