"""Data build configs (``conf/data/*.yaml``): the schema, its checks, and the exact form kept in manifests.

The file is read with :func:`radar2shape.structured_config.load_structured`, so unknown keys, wrong
types and YAML errors are one line naming the file and key. Every other check sits in
``BuildConfig.__post_init__`` and runs before a build writes anything, so a bad config never
leaves an output folder behind.

The ``radar`` section is either a path to a radar grid YAML (``conf/radar/default.yaml``, the same
keys ``RadarGrid.from_config`` reads) or those keys inline; ``{config: PATH, key: value}`` takes
the file and overrides keys. Relative paths (``radar``, ``family_options.root``) resolve against
the working directory first, then against the folders above the data config (so both ``make data``
and other working directories work).
"""

from __future__ import annotations

import inspect
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, Optional

from radar2shape.errors import UserInputError
from radar2shape.geometry.prepare import MeshConfig
from radar2shape.geometry.sampling import SamplingConfig
from radar2shape.structured_config import read_yaml, structured

DEFAULT_RADAR = "conf/radar/default.yaml"


@dataclass
class SimulatorOptions:
    """Keys the ``simulator`` section may set (unset ones keep ``simulate``'s defaults)."""

    method: Optional[str] = None  # "po" (default), "sbr", "po+ec" or "sbr+ec"
    max_bounces: Optional[int] = None  # sbr: bounces traced, >= 1 (checked whatever the method)
    rays_per_wavelength: Optional[float] = None  # sbr: ray tubes per wavelength, > 0
    shadowing: Optional[bool] = None
    polarization: Optional[str] = None  # "VV" (default), "HH", "HV" or "VH": records hold one channel
    edge_threshold_deg: Optional[float] = None  # +ec methods: sharp-edge normal turn in degrees
    edge_krho: Optional[float] = None  # +ec methods: rounded edges count while k * radius <= this (0: none)
    edge_order: Optional[int] = None  # +ec methods: 1 single diffraction, 2 (default) plus facing sheet edges


@dataclass
class BuildConfig:
    """Everything that determines a built dataset; equal configs give byte-equal records."""

    family: str
    family_options: dict[str, Any] = field(default_factory=dict)
    seed: int = 0
    num: Optional[int] = None  # shapes in all splits (procedural: required; folder: optional cap)
    splits: dict[str, float] = field(default_factory=lambda: {"train": 0.8, "val": 0.1, "test": 0.1})
    mesh: MeshConfig = field(default_factory=MeshConfig)
    sampling: SamplingConfig = field(default_factory=SamplingConfig)
    radar: dict[str, Any] = field(default_factory=dict)  # resolved RadarGrid.from_config keys
    simulator: dict[str, Any] = field(default_factory=dict)  # simulate() options, only those set
    floor_db: float = -100.0  # dB floor of the radar statistics stored in the manifest

    def __post_init__(self):
        """The checks types cannot express, so that a build fails before it writes anything."""
        from radar2shape.geometry.families import FAMILIES
        from radar2shape.radar import RadarGrid
        from radar2shape.radar.edges import check_krho, check_order, check_threshold
        from radar2shape.radar.sbr import DEFAULT_BOUNCES, DEFAULT_RAYS_PER_WAVELENGTH, check_options

        self.sampling = replace(self.sampling, sdf_near_sigmas=tuple(self.sampling.sdf_near_sigmas))
        families = {**FAMILIES, **_data_families()}
        if self.family not in families:
            raise UserInputError(f"family: unknown family {self.family!r}; choose from {sorted(families)}")
        accepted = [name for name in inspect.signature(families[self.family]).parameters if name != "self"]
        unknown = sorted(set(self.family_options) - set(accepted))
        if unknown:
            raise UserInputError(f"family_options: unknown key(s) {unknown} for family {self.family!r}; "
                                 f"expected some of {accepted}")
        if self.num is not None and self.num < 1:
            raise UserInputError(f"num: expected a positive number of shapes, got {self.num}")
        if self.num is None and self.family not in ("folder", "real"):
            raise UserInputError(f"'num' must be a positive number of shapes for family {self.family!r}")
        bad_splits = sorted(set(self.splits) - {"train", "val", "test"})
        if bad_splits or any(v < 0 for v in self.splits.values()) or sum(self.splits.values()) <= 0:
            raise UserInputError(f"splits: expected train/val/test -> non-negative fractions with a positive sum, "
                                 f"got {self.splits}")
        for section, names in (("sampling", ("surface", "eval", "sdf", "occ")),
                               ("mesh", ("face_budget", "remesh_resolution", "max_input_faces"))):
            for name in names:
                if getattr(getattr(self, section), name) < 1:
                    raise UserInputError(f"{section}.{name}: expected a positive count, "
                                         f"got {getattr(getattr(self, section), name)}")
        if not 0.0 <= self.sampling.sdf_near_fraction <= 1.0 or self.sampling.padding < 0:
            raise UserInputError("sampling: sdf_near_fraction must lie in [0, 1] and padding be >= 0")
        if not self.sampling.sdf_near_sigmas or min(self.sampling.sdf_near_sigmas) <= 0:
            raise UserInputError(f"sampling.sdf_near_sigmas: expected positive numbers, got {self.sampling.sdf_near_sigmas}")
        options = structured(SimulatorOptions, self.simulator, "simulator")
        if options.method not in (None, "po", "sbr", "po+ec", "sbr+ec"):
            raise UserInputError(f"simulator.method: expected 'po' or 'sbr', either optionally with edge currents "
                                 f"('po+ec', 'sbr+ec'), got {options.method!r}")
        if options.polarization not in (None, "VV", "HH", "HV", "VH"):
            raise UserInputError(f"simulator.polarization: expected 'VV', 'HH', 'HV' or 'VH' (one channel per "
                                 f"record), got {options.polarization!r}")
        try:  # the simulator's own checks, named under this section, whatever the method uses
            if options.max_bounces is not None or options.rays_per_wavelength is not None:
                check_options(DEFAULT_BOUNCES if options.max_bounces is None else options.max_bounces,
                              DEFAULT_RAYS_PER_WAVELENGTH if options.rays_per_wavelength is None
                              else options.rays_per_wavelength)
            if options.edge_threshold_deg is not None:
                check_threshold(options.edge_threshold_deg)
            if options.edge_krho is not None:
                check_krho(options.edge_krho)
            if options.edge_order is not None:
                check_order(options.edge_order)
        except UserInputError as err:
            raise UserInputError(f"simulator.{err}") from None
        try:
            RadarGrid.from_config(self.radar)
        except UserInputError as err:
            raise UserInputError(f"radar: {err}") from None
        if not math.isfinite(self.floor_db):
            raise UserInputError(f"floor_db: expected a finite dB floor, got {self.floor_db}")
        self.make_family()  # option values, folder root

    def make_family(self):
        """The shape family this config builds from."""
        from radar2shape.geometry.families import make_family

        if self.family in _data_families():
            try:
                return _data_families()[self.family](**self.family_options)
            except TypeError as err:
                raise UserInputError(f"family_options for {self.family!r}: {err}") from err
        return make_family(self.family, self.family_options)

    def to_dict(self) -> dict:
        """Plain, JSON-ready form (tuples become lists), as stored in the manifest."""
        return _jsonable(asdict(self))


def _data_families() -> dict:
    """Families that live in data_modules (the radar2shape package never imports data_modules)."""
    from data_modules.real_sources import RealTargetsFamily

    return {"real": RealTargetsFamily}


def _jsonable(value):
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    return value


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
    """The radar grid keys: a file, inline keys, or a file with overrides."""
    if isinstance(value, str):
        value = {"config": value}
    if not isinstance(value, dict) or not value:
        raise UserInputError(f"{source}: key 'radar': expected a path to a radar YAML or a mapping of its keys")
    value = dict(value)
    if "config" in value:
        path = resolve_path(str(value.pop("config")), source.parent)
        if not path.is_file():
            raise UserInputError(f"{source}: key 'radar': radar config {path} not found")
        grid = read_yaml(path) or {}
        if not isinstance(grid, dict):
            raise UserInputError(f"{path}: expected a mapping of radar grid keys")
        value = {**grid, **value}
    return value


def load_build_config(path: str | Path, num: int | None = None) -> BuildConfig:
    """Read and check a data config; ``num`` overrides its ``num``."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"--config: {path} not found (see conf/data/ for examples)")
    raw = read_yaml(path)
    if not isinstance(raw, dict):
        raise UserInputError(f"{path}: expected a mapping of config keys, got {type(raw).__name__}")
    raw = dict(raw)
    if num is not None:
        raw["num"] = num
    raw["radar"] = _radar_section(raw.get("radar", DEFAULT_RADAR), path)
    options = raw.get("family_options")
    if isinstance(options, dict) and isinstance(options.get("root"), str):
        raw["family_options"] = {**options, "root": str(resolve_path(options["root"], path.parent))}
    if isinstance(options, dict) and isinstance(options.get("sources"), list):  # family real: one root per source
        raw["family_options"] = {**raw.get("family_options", options), "sources": [
            {**source, "root": str(resolve_path(source["root"], path.parent))}
            if isinstance(source, dict) and isinstance(source.get("root"), str) else source
            for source in options["sources"]]}
    return structured(BuildConfig, raw, str(path))


def config_from_dict(data: dict) -> BuildConfig:
    """Inverse of ``BuildConfig.to_dict`` (used by the build's worker processes)."""
    return structured(BuildConfig, data, "build config")


def _largest_input_faces(config: BuildConfig) -> tuple[int, str] | None:
    """(faces, file) of a folder family's largest input file, from its header; None otherwise."""
    from radar2shape.preflight import count_faces

    if config.family != "folder":
        return None
    tasks = config.make_family().plan(config.num, config.splits, config.seed)
    root = Path(config.family_options["root"])
    files = [root / t.source for t in tasks if t.source]
    files = [f for f in files if f.is_file()]
    if not files:
        return None
    largest = max(files, key=lambda f: f.stat().st_size)
    faces = count_faces(largest)
    return None if faces is None else (faces, str(largest))


def check_build_memory(config: BuildConfig, workers: int, option_gb: float | None = None) -> None:
    """Refuse a build whose workers together would need more memory than the limit, before anything
    is written: per worker, the largest mesh it holds (a folder's largest input, else
    ``mesh.face_budget``), the radar grid, the point samples and the repair remesh grid."""
    from radar2shape.preflight import (BYTES_PER_CELL, BYTES_PER_SAMPLE, BYTES_PER_VOXEL, check_memory,
                                       mesh_bytes)
    from radar2shape.radar import RadarGrid

    grid = RadarGrid.from_config(config.radar)
    cells = grid.shape[0] * grid.shape[1] * grid.shape[2]
    s = config.sampling
    samples = s.surface + s.eval + s.sdf + s.occ
    largest = _largest_input_faces(config)
    faces = max(config.mesh.face_budget, largest[0] if largest else 0)
    per_worker = (mesh_bytes(faces) + cells * BYTES_PER_CELL + samples * BYTES_PER_SAMPLE
                  + config.mesh.remesh_resolution ** 3 * BYTES_PER_VOXEL)
    source = f"the largest input {largest[1]}" if largest and largest[0] >= config.mesh.face_budget else "mesh.face_budget"
    check_memory(workers * per_worker,
                 f"build-data with {workers} worker(s) (each: a {faces}-face mesh from {source}, a {grid.shape[0]} x "
                 f"{grid.shape[1]} x {grid.shape[2]} radar grid, {samples} sample points, a "
                 f"{config.mesh.remesh_resolution}^3 remesh grid)", option_gb)
