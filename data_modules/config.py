"""Data build configs (``conf/data/*.yaml``): parsing, checking, and the exact form kept in manifests.

The ``radar`` section is either a path to a radar grid YAML (``conf/radar/default.yaml``, the same
keys ``RadarGrid.from_config`` reads) or those keys inline; ``{config: PATH, key: value}`` takes
the file and overrides keys. Relative paths resolve against the working directory first, then
against the folders above the data config (so both ``make data`` and other working directories
work).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import yaml

from radar2shape.errors import UserInputError
from radar2shape.geometry.prepare import MeshConfig
from radar2shape.geometry.sampling import SamplingConfig


@dataclass
class BuildConfig:
    """Everything that determines a built dataset; equal configs give byte-equal records."""

    family: str
    family_options: dict = field(default_factory=dict)
    seed: int = 0
    num: int | None = None  # shapes in all splits (procedural: required; folder: optional cap)
    splits: dict = field(default_factory=lambda: {"train": 0.8, "val": 0.1, "test": 0.1})
    mesh: MeshConfig = field(default_factory=MeshConfig)
    sampling: SamplingConfig = field(default_factory=SamplingConfig)
    radar: dict = field(default_factory=dict)  # resolved RadarGrid.from_config keys
    simulator: dict = field(default_factory=dict)  # simulate() options: method, max_bounces, ...
    floor_db: float = -100.0  # dB floor of the radar statistics stored in the manifest

    def to_dict(self) -> dict:
        """Plain, JSON-ready form (tuples become lists), as stored in the manifest."""
        return _jsonable(asdict(self))


def _jsonable(value):
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


def _check_keys(values: dict, cls, prefix: str, where: str = "") -> None:
    """Name the keys of ``values`` that dataclass ``cls`` has no field for (typos fail loudly)."""
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise UserInputError(f"{prefix}unknown key(s) {unknown}{where}; expected some of {sorted(known)}")


def _section(cls, values, name: str, source: str):
    """Build dataclass ``cls`` from a mapping, naming unknown keys in the error."""
    values = values or {}
    if not isinstance(values, dict):
        raise UserInputError(f"{source}: '{name}' must be a mapping, got {type(values).__name__}")
    _check_keys(values, cls, f"{source}: ", f" in '{name}'")
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
    return cls(**values)


def resolve_path(path: str, anchor: Path) -> Path:
    """``path`` as given if it exists, else relative to ``anchor`` or one of its parents."""
    candidate = Path(path).expanduser()
    if candidate.is_absolute() or candidate.exists():
        return candidate
    for folder in [anchor, *anchor.parents]:
        if (folder / candidate).exists():
            return folder / candidate
    return candidate


def _radar_section(value, source: Path) -> dict:
    if isinstance(value, str):
        value = {"config": value}
    if not isinstance(value, dict) or not value:
        raise UserInputError(f"{source}: 'radar' must be a path to a radar YAML or a mapping of its keys")
    value = dict(value)
    if "config" in value:
        path = resolve_path(value.pop("config"), source.parent)
        if not path.is_file():
            raise UserInputError(f"{source}: radar config {path} not found")
        value = {**(yaml.safe_load(path.read_text()) or {}), **value}
    return value


SIMULATOR_KEYS = {"method", "max_bounces", "rays_per_wavelength", "shadowing"}


def _simulator_section(value, source: Path) -> dict:
    """Options passed to ``simulate`` (empty = physical optics with shadowing)."""
    value = dict(value or {})
    unknown = sorted(set(value) - SIMULATOR_KEYS)
    if unknown:
        raise UserInputError(f"{source}: unknown key(s) {unknown} in 'simulator'; expected some of {sorted(SIMULATOR_KEYS)}")
    if value.get("method", "po") not in ("po", "sbr"):
        raise UserInputError(f"{source}: simulator.method must be 'po' or 'sbr', got {value['method']!r}")
    return value


def load_build_config(path: str | Path, num: int | None = None) -> BuildConfig:
    """Read and check a data config; ``num`` overrides its ``num``."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"--config: {path} not found (see conf/data/ for examples)")
    raw = yaml.safe_load(path.read_text()) or {}
    if not isinstance(raw, dict):
        raise UserInputError(f"{path}: expected a mapping of config keys")
    _check_keys(raw, BuildConfig, f"{path}: ")
    if "family" not in raw:
        raise UserInputError(f"{path}: missing 'family' (frusta, parts or folder)")
    config = BuildConfig(
        family=raw["family"],
        family_options=dict(raw.get("family_options") or {}),
        seed=int(raw.get("seed", 0)),
        num=num if num is not None else raw.get("num"),
        splits=dict(raw.get("splits") or BuildConfig.__dataclass_fields__["splits"].default_factory()),
        mesh=_section(MeshConfig, raw.get("mesh"), "mesh", str(path)),
        sampling=_section(SamplingConfig, raw.get("sampling"), "sampling", str(path)),
        radar=_radar_section(raw.get("radar", "conf/radar/default.yaml"), path),
        simulator=_simulator_section(raw.get("simulator"), path),
        floor_db=float(raw.get("floor_db", -100.0)),
    )
    if "root" in config.family_options:
        config.family_options["root"] = str(resolve_path(config.family_options["root"], path.parent))
    if config.family != "folder" and (config.num is None or int(config.num) <= 0):
        raise UserInputError(f"{path}: 'num' must be a positive number of shapes for family {config.family!r}")
    bad_splits = sorted(set(config.splits) - {"train", "val", "test"})
    if bad_splits or any(float(v) < 0 for v in config.splits.values()):
        raise UserInputError(f"{path}: 'splits' maps train/val/test to non-negative fractions, got {config.splits}")
    return config


def config_from_dict(data: dict) -> BuildConfig:
    """Inverse of ``BuildConfig.to_dict`` (used by workers and when reading manifests)."""
    data = dict(data)
    data["mesh"] = _section(MeshConfig, data.get("mesh"), "mesh", "build config")
    data["sampling"] = _section(SamplingConfig, data.get("sampling"), "sampling", "build config")
    return BuildConfig(**data)
