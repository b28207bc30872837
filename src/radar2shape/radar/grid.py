"""``RadarGrid``: the aspect, roll and frequency axes of a response and the object's size.

Configs speak degrees and GHz (conf/radar/*.yaml); the grid holds radians and hertz.
An axis is either ``{start, stop, count, endpoint}`` (linspace; endpoint defaults to true) or
an explicit list of values.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from radar2shape.errors import UserInputError
from radar2shape.radar.simulator import check_axes, directions

# Mirrors conf/radar/default.yaml (a test keeps the two equal).
DEFAULT_CONFIG = {
    "aspect_deg": {"start": 0.0, "stop": 180.0, "count": 32},
    "roll_deg": {"start": 0.0, "stop": 360.0, "count": 32, "endpoint": False},
    "freq_ghz": {"start": 8.0, "stop": 12.0, "count": 64},
    "size_m": 1.0,
}
_AXES = {"aspect_deg": np.pi / 180.0, "roll_deg": np.pi / 180.0, "freq_ghz": 1e9}


def axis_values(spec, name: str) -> np.ndarray:
    """Values of one axis spec in config units (degrees or GHz)."""
    if isinstance(spec, Mapping):
        unknown = set(spec) - {"start", "stop", "count", "endpoint"}
        if unknown or not {"start", "stop", "count"} <= set(spec):
            raise UserInputError(f"{name}: expected keys start, stop, count[, endpoint], got {sorted(spec)}")
        count = spec["count"]
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
            raise UserInputError(f"{name}.count: expected a positive integer, got {count!r}")
        try:
            return np.linspace(float(spec["start"]), float(spec["stop"]), int(count),
                               endpoint=bool(spec.get("endpoint", True)))
        except (TypeError, ValueError) as err:
            raise UserInputError(f"{name}: start/stop must be numbers ({err})") from err
    if isinstance(spec, (Sequence, np.ndarray)) and not isinstance(spec, str):  # lists, OmegaConf ListConfig
        try:
            return np.asarray(spec, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise UserInputError(f"{name}: expected a list of numbers ({err})") from err
    raise UserInputError(f"{name}: expected {{start, stop, count}} or a list, got {type(spec).__name__}")


@dataclass(frozen=True, eq=False)
class RadarGrid:
    """Axes in radians and hertz; ``size_m`` is the longest side the object is simulated at."""

    aspect_rad: np.ndarray
    roll_rad: np.ndarray
    freq_hz: np.ndarray
    size_m: float = 1.0

    def __post_init__(self):
        aspect, roll, freq = check_axes(self.aspect_rad, self.roll_rad, self.freq_hz)
        if not np.isfinite(self.size_m) or self.size_m <= 0:
            raise UserInputError(f"size_m: expected a positive number of metres, got {self.size_m!r}")
        for name, value in (("aspect_rad", aspect), ("roll_rad", roll), ("freq_hz", freq)):
            value = value.copy()  # never freeze the caller's array
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "size_m", float(self.size_m))

    @property
    def shape(self) -> tuple[int, int, int]:
        return len(self.aspect_rad), len(self.roll_rad), len(self.freq_hz)

    def directions(self) -> np.ndarray:
        """[A, R, 3] unit vectors toward the radar."""
        return directions(self.aspect_rad, self.roll_rad)

    @classmethod
    def from_config(cls, config: Mapping) -> RadarGrid:
        """Grid from a config dict (degrees/GHz); missing keys take the default grid's values."""
        if not isinstance(config, Mapping):
            raise UserInputError(f"radar grid config: expected a mapping, got {type(config).__name__}")
        unknown = set(config) - set(DEFAULT_CONFIG)
        if unknown:
            raise UserInputError(f"radar grid config: unknown keys {sorted(unknown)} (expected {sorted(DEFAULT_CONFIG)})")
        merged = {**DEFAULT_CONFIG, **config}
        axes = {name: axis_values(merged[name], name) * scale for name, scale in _AXES.items()}
        try:
            size = float(merged["size_m"])
        except (TypeError, ValueError) as err:
            raise UserInputError(f"size_m: expected a number, got {merged['size_m']!r}") from err
        return cls(axes["aspect_deg"], axes["roll_deg"], axes["freq_ghz"], size)

    @classmethod
    def from_yaml(cls, path: str | Path) -> RadarGrid:
        try:
            config = yaml.safe_load(Path(path).read_text())
        except (OSError, yaml.YAMLError) as err:
            raise UserInputError(f"{path}: cannot read radar grid config ({err})") from err
        return cls.from_config(config or {})

    @classmethod
    def default(cls) -> RadarGrid:
        """32 aspects over [0, pi], 32 rolls over [0, 2pi), 64 frequencies over 8-12 GHz, 1 m."""
        return cls.from_config(DEFAULT_CONFIG)

    def to_config(self) -> dict:
        """Explicit per-value config (degrees/GHz) that ``from_config`` turns back into this grid."""
        return {
            "aspect_deg": np.degrees(self.aspect_rad).tolist(),
            "roll_deg": np.degrees(self.roll_rad).tolist(),
            "freq_ghz": (self.freq_hz / 1e9).tolist(),
            "size_m": self.size_m,
        }
