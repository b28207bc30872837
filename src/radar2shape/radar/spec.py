"""``RadarSpec``: the radar a model was trained on, its grid and the dB normalisation of its input.

A dataset has one spec (``data_modules`` builds it from the manifest and the train statistics);
a model adopts its DataModule's spec at fit start and stores it in every checkpoint, so
inference (``radar2shape reconstruct``, measured data) normalises exactly as training did, with
no dataset at hand. :meth:`RadarSpec.normalise` is the one place the dB standardisation lives.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from radar2shape.errors import UserInputError
from radar2shape.radar.grid import RadarGrid
from radar2shape.radar.signal import to_db

AXES = ("aspect_rad", "roll_rad", "freq_hz")
KEYS = (*AXES, "size_m", "roll_symmetric", "floor_db", "db_mean", "db_std")


def _number(value, name: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not np.isfinite(value):
        raise UserInputError(f"{source}: '{name}' must be a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True, eq=False)
class RadarSpec:
    """A radar grid, whether inputs are aspect-only, and the dB floor and train statistics.

    ``roll_symmetric``: the data is a body of revolution seen along one meridian, so the model
    input is ``[A, F]`` at the grid's single roll angle (``grid.roll_rad`` has one value).
    Otherwise the input is the full ``[A, R, F]``.
    """

    grid: RadarGrid
    db_mean: float
    db_std: float
    floor_db: float = -100.0
    roll_symmetric: bool = False

    def __post_init__(self):
        for name in ("db_mean", "db_std", "floor_db"):
            object.__setattr__(self, name, _number(getattr(self, name), name, "radar spec"))
        if self.db_std <= 0:
            raise UserInputError(f"radar spec: 'db_std' must be positive, got {self.db_std!r}")
        if self.roll_symmetric and len(self.grid.roll_rad) != 1:
            raise UserInputError(f"radar spec: a roll-symmetric spec has one roll angle, got {len(self.grid.roll_rad)}")
        object.__setattr__(self, "roll_symmetric", bool(self.roll_symmetric))

    @property
    def input_shape(self) -> tuple[int, ...]:
        """Shape of one model input: ``(A, F)`` when roll-symmetric, else ``(A, R, F)``."""
        aspect, roll, freq = self.grid.shape
        return (aspect, freq) if self.roll_symmetric else (aspect, roll, freq)

    def to_db(self, response: np.ndarray) -> np.ndarray:
        """dBsm of a complex response, clipped at this spec's floor."""
        return to_db(response, self.floor_db)

    def denormalise(self, x: np.ndarray) -> np.ndarray:
        """dB from a model input ``(dB - mean) / std`` (masked cells come back as the train mean)."""
        return np.asarray(x, dtype=np.float64) * self.db_std + self.db_mean

    def normalise(self, db: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
        """float32 ``(dB - mean) / std``; 0 (the train mean) in masked cells and wherever dB is NaN.

        ``mask`` (True = observed) covers the leading axes of ``db`` (``[A, R]`` of ``[A, R, F]``,
        ``[A]`` of ``[A, F]``). Models have a mask channel per cell but none per frequency, so a
        frequency without data (NaN) takes the value a masked cell takes.
        """
        out = (np.asarray(db) - self.db_mean) / self.db_std
        if mask is not None:
            mask = np.asarray(mask, dtype=bool)
            if mask.shape != out.shape[: mask.ndim]:
                raise ValueError(f"mask {mask.shape} does not cover the leading axes of dB {out.shape}")
            out = np.where(mask.reshape(mask.shape + (1,) * (out.ndim - mask.ndim)), out, 0.0)
        return np.nan_to_num(out, nan=0.0).astype(np.float32)

    # ---- primitives for checkpoints (torch.load(weights_only=True) reads them) ----------------
    def to_dict(self) -> dict:
        """Lists, floats and a bool only; :meth:`from_dict` turns it back into this spec."""
        return {
            **{axis: np.asarray(getattr(self.grid, axis), dtype=float).tolist() for axis in AXES},
            "size_m": float(self.grid.size_m),
            "roll_symmetric": self.roll_symmetric,
            "floor_db": self.floor_db,
            "db_mean": self.db_mean,
            "db_std": self.db_std,
        }

    @classmethod
    def from_dict(cls, data: Mapping, source: str = "radar spec") -> RadarSpec:
        """The spec :meth:`to_dict` wrote; ``source`` names where it came from in errors."""
        if not isinstance(data, Mapping):
            raise UserInputError(f"{source}: expected a mapping of {', '.join(KEYS)}, got {type(data).__name__}")
        missing, unknown = [k for k in KEYS if k not in data], sorted(set(data) - set(KEYS))
        if missing or unknown:
            raise UserInputError(f"{source}: missing keys {missing}, unknown keys {unknown} (expected {', '.join(KEYS)})")
        try:
            axes = [np.asarray(data[axis], dtype=float) for axis in AXES]
        except (TypeError, ValueError) as err:
            raise UserInputError(f"{source}: axes must be lists of numbers ({err})") from err
        grid = RadarGrid(*axes, _number(data["size_m"], "size_m", source))
        if not isinstance(data["roll_symmetric"], (bool, np.bool_)):
            raise UserInputError(f"{source}: 'roll_symmetric' must be true or false, got {data['roll_symmetric']!r}")
        return cls(grid, _number(data["db_mean"], "db_mean", source), _number(data["db_std"], "db_std", source),
                   _number(data["floor_db"], "floor_db", source), bool(data["roll_symmetric"]))

    @classmethod
    def from_manifest(cls, radar: Mapping, stats: Mapping, roll_symmetric: bool = False) -> RadarSpec:
        """The spec of a built dataset: its manifest's ``radar`` axes and train ``stats`` (``floor_db, mean, std``).

        ``roll_symmetric`` keeps the first roll angle only, the one aspect-only inputs are cut at.
        """
        roll = np.asarray(radar["roll_rad"], dtype=float)
        grid = RadarGrid(np.asarray(radar["aspect_rad"], dtype=float), roll[:1] if roll_symmetric else roll,
                         np.asarray(radar["freq_hz"], dtype=float), float(radar.get("size_m", 1.0)))
        return cls(grid, stats["mean"], stats["std"], stats["floor_db"], roll_symmetric)

    def __eq__(self, other) -> bool:
        return isinstance(other, RadarSpec) and self.to_dict() == other.to_dict()

    __hash__ = None

    def describe(self) -> str:
        """One line for logs and errors: grid sizes, band, statistics."""
        freq = self.grid.freq_hz
        shape = " x ".join(str(n) for n in self.input_shape)
        return (f"{shape} ({'aspect x freq, roll-symmetric' if self.roll_symmetric else 'aspect x roll x freq'}), "
                f"{freq.min() / 1e9:.6g}-{freq.max() / 1e9:.6g} GHz, {self.grid.size_m:g} m, "
                f"dB mean {self.db_mean:.4g} std {self.db_std:.4g} floor {self.floor_db:g}")
