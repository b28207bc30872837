"""RadarSpec: the one dB normalisation, and a checkpoint-safe round trip."""

import numpy as np
import pytest
import torch

from radar2shape.errors import UserInputError
from radar2shape.radar import RadarGrid
from radar2shape.radar.spec import RadarSpec

GRID = RadarGrid(np.linspace(0, np.pi, 3), np.linspace(0, np.pi, 2, endpoint=False), np.array([8e9, 10e9]), 0.5)


def test_normalise_standardises_and_zeroes_masked_and_missing_cells():
    spec = RadarSpec(GRID, db_mean=-20.0, db_std=4.0, floor_db=-60.0)
    db = np.full((3, 2, 2), -12.0)
    db[0, 1, 1] = np.nan  # a frequency the file does not cover
    mask = np.ones((3, 2), bool)
    mask[2, 0] = False
    out = spec.normalise(db, mask)
    assert out.dtype == np.float32 and out.shape == (3, 2, 2)
    assert out[0, 0, 0] == 2.0 and out[0, 1, 1] == 0.0 and (out[2, 0] == 0).all()
    assert np.count_nonzero(out) == 12 - 1 - 2
    # an aspect-only [A, F] input with an [A] mask, and the floor of to_db
    out = spec.normalise(spec.to_db(np.array([[1e-9, 1.0], [0.1, 0.1]])), np.array([True, False]))
    np.testing.assert_allclose(out, [[(-60 + 20) / 4, 5.0], [0, 0]])
    with pytest.raises(ValueError, match="mask"):
        spec.normalise(db, np.ones((2, 2), bool))


def test_dict_round_trip_through_a_weights_only_checkpoint(tmp_path):
    spec = RadarSpec(RadarGrid(GRID.aspect_rad, [0.0], GRID.freq_hz, 0.5), -31.5, 9.25, -80.0, roll_symmetric=True)
    torch.save({"radar_spec": spec.to_dict()}, tmp_path / "c.ckpt")
    loaded = RadarSpec.from_dict(torch.load(tmp_path / "c.ckpt", weights_only=True)["radar_spec"])
    assert loaded == spec and loaded.input_shape == (3, 2) and loaded.grid.size_m == 0.5
    np.testing.assert_array_equal(loaded.grid.aspect_rad, GRID.aspect_rad)
    assert loaded != RadarSpec(GRID, -31.5, 9.25, -80.0)


def test_from_manifest_keeps_the_first_roll_for_aspect_only_data():
    radar = {"aspect_rad": [0.0, 1.0], "roll_rad": [0.0, 1.0, 2.0], "freq_hz": [1e9], "size_m": 2.0}
    stats = {"floor_db": -100.0, "mean": -40.0, "std": 8.0}
    assert RadarSpec.from_manifest(radar, stats).input_shape == (2, 3, 1)
    spec = RadarSpec.from_manifest(radar, stats, roll_symmetric=True)
    assert spec.grid.roll_rad.tolist() == [0.0] and spec.input_shape == (2, 1) and spec.db_std == 8.0


@pytest.mark.parametrize("change, message", [
    ({"db_std": 0.0}, "'db_std' must be positive"),
    ({"db_mean": "x"}, "'db_mean' must be a finite number"),
    ({"roll_symmetric": 1}, "'roll_symmetric' must be true or false"),
    ({"extra": 1}, r"unknown keys \['extra'\]"),
    ({"freq_hz": [-1.0, 1.0]}, "freq_hz"),
])
def test_bad_dicts_are_one_line_errors(change, message):
    data = {**RadarSpec(GRID, -20.0, 4.0).to_dict(), **change}
    with pytest.raises(UserInputError, match=message):
        RadarSpec.from_dict(data, "model.ckpt: radar_spec")
    with pytest.raises(UserInputError, match=r"missing keys \['db_std'\]"):
        RadarSpec.from_dict({k: v for k, v in RadarSpec(GRID, -20.0, 4.0).to_dict().items() if k != "db_std"})
