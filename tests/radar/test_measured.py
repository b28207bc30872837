"""Measured radar: readers (Austin text, generic CSV / NPZ), named errors, and resampling rules."""

import numpy as np
import pytest

from radar2shape.errors import UserInputError
from radar2shape.geometry.families.monocone import Monocone
from radar2shape.geometry.profile import profile_to_mesh
from radar2shape.radar import RadarGrid, save_response, simulate, to_db
from radar2shape.radar.measured import (
    Measurement,
    full_circle,
    interpolate_axis,
    read_austin,
    read_csv,
    read_measured,
    read_npz,
    resample,
    write_csv,
)
from radar2shape.radar.spec import RadarSpec
from radar2shape.radar.validation import read_cut

ALMOND = "austin-rcs/almond-IIIA"
MODEL_ASPECT = np.radians(np.linspace(0, 180, 16))
MODEL_ROLL = np.radians(np.linspace(0, 360, 16, endpoint=False))
MODEL_FREQ = np.linspace(8e9, 12e9, 16)


def spec_for(grid, db_mean: float, db_std: float) -> RadarSpec:
    """A spec whose statistics are given (its axes only need the input's shape)."""
    a, r, f = grid.db.shape
    return RadarSpec(RadarGrid(np.zeros(a), np.zeros(r), np.ones(f)), db_mean, db_std)


def file_rows(path):
    """The file's rows as the text says them, parsed independently of the reader."""
    return [tuple(float(x) for x in line.split()) for line in path.read_text().splitlines() if line.strip()]


# ---- Austin ---------------------------------------------------------------------------------------
def test_austin_almond_file_grid_units_and_values(shared_validation):
    path = shared_validation / ALMOND / "meas.m1_rcs.III.A.s1.fx1.H.txt"
    rows = file_rows(path)
    m = read_austin(path)
    assert m.db.shape == (1, 721, 1) and m.aspect_only is False
    assert m.freq_hz.tolist() == [3.5e9]  # Hz as in the file
    assert m.aspect_rad.tolist() == [np.pi / 2]  # theta 90 deg -> aspect in radians
    np.testing.assert_allclose(np.degrees(m.roll_rad), np.arange(721) * 0.25, atol=1e-12)  # phi 0..180 every 0.25
    np.testing.assert_array_equal(m.db[0, :, 0], [r[3] for r in rows])  # dBsm untouched
    assert m.db[0, 0, 0] == -29.265346 and m.db[0, 1, 0] == -29.261377  # the first two lines of the file


def test_austin_files_combine_along_frequency(shared_validation):
    paths = sorted((shared_validation / ALMOND).glob("ref_rcs.III.A.s1.fx*.V.txt"))
    m = read_measured(paths, "austin")
    assert m.freq_hz.tolist() == [3.5e9, 5.12e9, 7.0e9, 10.25e9]
    assert m.db.shape == (1, 361, 4) and np.isfinite(m.db).all()
    for j, path in enumerate(paths):
        np.testing.assert_array_equal(m.db[0, :, j], [r[3] for r in file_rows(path)])
    cut = read_cut(paths[2])  # the validation code reads through the same reader
    assert cut.freq_hz == 7.0e9 and cut.theta_rad == np.pi / 2
    np.testing.assert_array_equal(cut.rcs_db, m.db[0, :, 2])
    with pytest.raises(UserInputError, match="given twice"):
        read_austin([paths[0], paths[0]])


def test_almond_cut_on_a_model_grid(shared_validation):
    """theta = 90 deg, phi 0..180, 3.5-10.25 GHz onto 16 x 16 x 16 (0-180 deg, 0-337.5 deg, 8-12 GHz)."""
    paths = sorted((shared_validation / ALMOND).glob("meas.m1_rcs.III.A.s1.fx*.H.txt"))
    grid = resample(read_austin(paths), MODEL_ASPECT, MODEL_ROLL, MODEL_FREQ)
    assert grid.overlap == pytest.approx((10.25 - 8) / 4)
    # one aspect sample: it fills the model aspects within half a step (84 and 96 deg); the roll
    # cut covers 0..180 deg (columns 0-8); only 10.133 GHz lies within half a step of 10.25 GHz
    expected = np.zeros((16, 16), bool)
    expected[7:9, :9] = True
    np.testing.assert_array_equal(grid.mask, expected)
    assert np.flatnonzero(grid.freq_mask).tolist() == [8]
    fx4 = file_rows(paths[3])
    assert grid.db[7, 2, 8] == pytest.approx(fx4[180][3])  # roll 45 deg = line 181 (phi 45.00)
    assert np.isnan(grid.db[0]).all() and np.isnan(grid.db[7, 9:]).all()
    normalised = spec_for(grid, db_mean=-20.0, db_std=10.0).normalise(grid.db, grid.mask)
    assert (normalised[~grid.mask] == 0).all() and (normalised[..., ~grid.freq_mask] == 0).all()
    assert normalised[7, 2, 8] == pytest.approx((fx4[180][3] + 20) / 10, rel=1e-6)


def test_austin_sample_in_two_files(tmp_path):
    first = austin_file(tmp_path, ["1e10 90 0 -10", "1e10 90 1 -11"], "a.txt")
    second = austin_file(tmp_path, ["1e10 90 1 -12"], "b.txt")
    with pytest.raises(UserInputError, match=r"b.txt: line 1: duplicated sample .* already on .*a.txt: line 2"):
        read_austin([first, second])


def austin_file(tmp_path, lines, name="cut.txt"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    "lines, message",
    [
        (["1e10 90 0 -10", "1e10 90 1 -11", "1e10 90 0.5 -12"], r"line 3, column 'phi_deg': 0.5 comes after 1 on line 2"),
        (["1e10 90 0 -10", "1e10 90 1 -11", "1e10 90 1 -12"], r"line 3: duplicated sample .*phi_deg 1.* already on line 2"),
        (["1e10 90 0 -10", "1e10 90 1 nan"], r"line 2, column 'rcs_dbsm': nan \(NaN"),
        (["1e10 90 0 -10", "1e10 90 1"], r"line 2: missing column 'rcs_dbsm'"),
        (["1e10 90 0 -10", "1e10 ninety 1 -3"], r"line 2, column 'theta_deg': 'ninety' is not a number"),
    ],
)
def test_austin_bad_rows_name_file_line_and_column(tmp_path, lines, message):
    with pytest.raises(UserInputError, match=message) as err:
        read_austin(austin_file(tmp_path, lines))
    assert str(err.value).startswith(str(tmp_path / "cut.txt"))


# ---- generic CSV ----------------------------------------------------------------------------------
def csv_file(tmp_path, text, name="m.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_csv_dense_grid_with_missing_rows_and_complex_values(tmp_path):
    text = ("# comment line\naspect_deg,roll_deg,freq_ghz,re,im\n"
            "0,0,8,0.1,0\n0,0,9,0,0.2\n0,90,8,0.3,0.4\n10,0,9,1,0\n")
    m = read_csv(csv_file(tmp_path, text))
    assert m.db.shape == (2, 2, 2)
    np.testing.assert_allclose(m.aspect_rad, np.radians([0, 10]))
    np.testing.assert_allclose(m.roll_rad, np.radians([0, 90]))
    assert m.freq_hz.tolist() == [8e9, 9e9]
    expected = np.full((2, 2, 2), np.nan)
    expected[0, 0] = [-20.0, 20 * np.log10(0.2)]
    expected[0, 1, 0] = 20 * np.log10(0.5)  # |0.3 + 0.4j| = 0.5
    expected[1, 0, 1] = 0.0
    np.testing.assert_allclose(m.db, expected)


def test_csv_write_read_round_trip(tmp_path):
    aspect, freq = np.meshgrid([0.0, 45.0, 90.0], [8.0, 10.0], indexing="ij")
    db = -np.arange(6.0).reshape(3, 2) - 0.123456
    m = read_csv(write_csv(tmp_path / "w.csv", aspect.ravel(), freq.ravel(), db.ravel()))
    assert m.aspect_only and m.roll_rad.tolist() == [0.0]
    np.testing.assert_allclose(m.db[:, 0, :], db, atol=1e-6)


@pytest.mark.parametrize(
    "text, message",
    [
        ("aspect_deg,rcs_dbsm\n0,-10\n", r"line 1 \(header\): missing column 'freq_ghz'"),
        ("aspect_deg,freq_ghz\n0,8\n", r"line 1 \(header\): missing column 'rcs_dbsm'"),
        ("aspect_deg,freq_ghz,re\n0,8,1\n", r"missing column 'im'"),
        ("aspect_deg,freq_ghz,rcs_dbsm\n0,8,-10\n0,9\n", r"line 3: missing column 'rcs_dbsm'"),
        ("aspect_deg,freq_ghz,rcs_dbsm\n0,8,-10\n5,8,-10\n3,8,-10\n", r"line 4, column 'aspect_deg': 3 comes after 5 on line 3"),
        ("aspect_deg,freq_ghz,rcs_dbsm\n0,8,-10\n0,9,-10\n0,8.5,-10\n", r"line 4, column 'freq_ghz': 8.5 comes after 9"),
        ("aspect_deg,freq_ghz,rcs_dbsm\n0,8,-10\n0,8,-11\n", r"line 3: duplicated sample \(aspect_deg 0, freq_ghz 8\)"),
        ("aspect_deg,freq_ghz,rcs_dbsm\n0,8,-10\n1,8,NaN\n", r"line 3, column 'rcs_dbsm': NaN"),
        ("aspect_deg,freq_ghz,rcs_dbsm\n0,8,-10\n190,8,-10\n", r"line 3, column 'aspect_deg': 190 is outside 0..180"),
        ("aspect_deg,freq_ghz,rcs_dbsm\n", r"header only"),
    ],
)
def test_csv_bad_input_names_file_line_and_column(tmp_path, text, message):
    with pytest.raises(UserInputError, match=message) as err:
        read_csv(csv_file(tmp_path, text))
    assert str(err.value).startswith(str(tmp_path / "m.csv")) and "\n" not in str(err.value)


# ---- generic NPZ ----------------------------------------------------------------------------------
def test_npz_simulate_format_and_db_format(tmp_path):
    aspect, roll, freq = np.radians([0.0, 30.0]), np.radians([0.0, 180.0]), np.array([8e9, 9e9, 1e10])
    response = (np.arange(12).reshape(2, 2, 3) + 1).astype(np.complex64)
    m = read_npz(save_response(tmp_path / "s.npz", response, aspect, roll, freq))
    np.testing.assert_allclose(m.db, 20 * np.log10(np.abs(response)), rtol=1e-6)
    observed = np.ones((2, 3), bool)
    observed[1, 2] = False
    np.savez(tmp_path / "d.npz", aspect_rad=aspect, freq_hz=freq, rcs_dbsm=np.where(observed, -5.0, np.nan),
             observed=observed)
    m = read_npz(tmp_path / "d.npz")
    assert m.aspect_only and m.db.shape == (2, 1, 3)
    assert np.isnan(m.db[1, 0, 2]) and (m.db[m.observed] == -5.0).all()


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"freq_hz": None}, r"missing array\(s\) \['freq_hz'\]"),
        ({"aspect_rad": np.radians([0.0, 10.0, 10.0])}, r"'aspect_rad'\[2\] = 0.174533 duplicates 'aspect_rad'\[1\]"),
        ({"freq_hz": np.array([9e9, 8e9])}, r"'freq_hz'\[1\] = 8e\+09 is below 'freq_hz'\[0\]"),
        ({"rcs_dbsm": np.array([[-1.0, -2.0], [-3.0, np.nan], [-5.0, -6.0]])}, r"'rcs_dbsm'\[1, 1\] is NaN"),
        ({"aspect_rad": np.radians([0.0, 10.0, 200.0])}, r"'aspect_rad'\[2\] = 3.49066 is outside"),
    ],
)
def test_npz_bad_input_names_array_and_index(tmp_path, fields, message):
    base = {"aspect_rad": np.radians([0.0, 10.0, 20.0]), "freq_hz": np.array([8e9, 9e9]),
            "rcs_dbsm": -np.ones((3, 2))}
    base.update(fields)
    np.savez(tmp_path / "bad.npz", **{k: v for k, v in base.items() if v is not None})
    with pytest.raises(UserInputError, match=message):
        read_npz(tmp_path / "bad.npz")


def test_format_from_suffix_or_named(tmp_path):
    with pytest.raises(UserInputError, match="--format"):
        read_measured(tmp_path / "data.dat")
    with pytest.raises(UserInputError, match="reads one file"):
        read_measured([tmp_path / "a.csv", tmp_path / "b.csv"], "csv")


# ---- resampling -----------------------------------------------------------------------------------
def aspect_only_csv(tmp_path, aspects_deg, freqs_ghz, name="a.csv", value=None):
    a, f = np.meshgrid(aspects_deg, freqs_ghz, indexing="ij")
    db = value(a, f) if value else -20 - 0.1 * a + f
    return write_csv(tmp_path / name, a.ravel(), f.ravel(), db.ravel())


def test_interpolation_is_linear_and_wraps_roll():
    source = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    target = np.array([2 * np.pi - 0.1, 0.05, 7.0])  # across the seam and beyond 2 pi
    out = interpolate_axis(np.cos(source)[None, :, None], source, target, 1, periodic=True)[0, :, 0]
    closed = np.append(source, 2 * np.pi), np.append(np.cos(source), 1.0)
    np.testing.assert_allclose(out, [np.interp(t % (2 * np.pi), *closed) for t in target], atol=1e-12)
    assert full_circle(source) and not full_circle(np.radians([-10, 0, 10]))
    line = interpolate_axis(np.arange(5.0), np.arange(5.0), np.array([0.5, 3.25]), 0)
    np.testing.assert_allclose(line, [0.5, 3.25])


def test_missing_samples_are_masked_never_filled():
    source = np.arange(10.0)  # target step 1: gaps up to 2 steps are bridged linearly
    values = source.copy()
    values[[4, 7, 8]] = np.nan  # gaps 3..5 (bridged) and 6..9 (too wide)
    out = interpolate_axis(values, source, np.arange(12.0) + 0.5, 0)
    # 6.5 and 8.5 / 9.5 take the nearest sample within half a step; 7.5 and beyond 10 stay masked
    expected = [0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.0, np.nan, 9.0, 9.0, np.nan, np.nan]
    np.testing.assert_array_equal(out, expected)


def test_partial_aspects_are_masked_and_roll_is_repeated(tmp_path):
    m = read_csv(aspect_only_csv(tmp_path, np.arange(0, 61, 2.0), np.linspace(7, 13, 13)))
    with pytest.raises(UserInputError, match="--roll-symmetric"):
        resample(m, MODEL_ASPECT, MODEL_ROLL, MODEL_FREQ)
    grid = resample(m, MODEL_ASPECT, MODEL_ROLL, MODEL_FREQ, roll_symmetric=True, calibration_db=3.0)
    observed = np.degrees(MODEL_ASPECT) <= 60 + 1e-9  # 0, 12, ..., 60 deg
    np.testing.assert_array_equal(grid.mask, np.repeat(observed[:, None], 16, axis=1))
    assert grid.freq_mask.all() and grid.overlap == 1.0
    assert (grid.db == grid.db[:, :1]).all(where=grid.mask[..., None])  # every roll column is the same
    a, f = np.degrees(MODEL_ASPECT[5]), MODEL_FREQ / 1e9
    np.testing.assert_allclose(grid.db[5, 7], -20 - 0.1 * a + f + 3.0, atol=1e-9)  # linear data, +3 dB calibration
    assert np.isnan(grid.db[~grid.mask]).all()


def test_partly_overlapping_band(tmp_path):
    m = read_csv(aspect_only_csv(tmp_path, [0.0, 90.0, 180.0], np.linspace(9.6, 14, 12)))
    grid = resample(m, MODEL_ASPECT, [0.0], MODEL_FREQ, roll_symmetric=True, max_gap_steps=60)
    assert grid.overlap == pytest.approx(0.6)
    np.testing.assert_array_equal(grid.freq_mask, MODEL_FREQ >= 9.6e9 - 1e8 / 3)  # within half a step of 9.6
    normalised = spec_for(grid, db_mean=0.0, db_std=1.0).normalise(grid.db, grid.mask)
    assert grid.mask.all() and (normalised[..., ~grid.freq_mask] == 0).all()
    with pytest.raises(UserInputError, match=r"covers 60 % of the model's 8-12 GHz; at least 70 % is needed"):
        resample(m, MODEL_ASPECT, [0.0], MODEL_FREQ, roll_symmetric=True, min_overlap=0.7)


def test_size_scaling_is_electromagnetic_similarity():
    """PO of a cone at half size and twice the frequency, scaled back, equals PO at full size."""
    mesh = profile_to_mesh(Monocone(0.3, np.radians(20.0), 0.06).profile(4), segments=16)
    aspect, freq = np.radians([0.0, 30.0, 90.0, 150.0]), np.array([8e9, 10e9, 12e9])
    full = to_db(simulate(mesh, aspect, [0.0], freq), -200)
    half = simulate(mesh.copy().apply_scale(0.5), aspect, [0.0], 2 * freq)
    measured = Measurement(to_db(half, -200), aspect, np.zeros(1), 2 * freq, "half")
    grid = resample(measured, aspect, [0.0], freq, size_m=0.5, model_size_m=1.0, roll_symmetric=True,
                    floor_db=-200)
    np.testing.assert_allclose(grid.db, full, atol=1e-3)
    assert np.abs(to_db(half, -200) - full).max() > 5.0  # unscaled, the level differs by 20 log10 2 = 6 dB


def test_an_arc_of_roll_across_zero(tmp_path):
    """Rolls -30..30 deg cover the model rolls 337.5, 0 and 22.5 deg; the others are masked."""
    a, r, f = np.meshgrid([90.0], np.arange(-30.0, 31.0, 5.0), [8.0, 12.0], indexing="ij")
    m = read_csv(write_csv(tmp_path / "r.csv", a.ravel(), f.ravel(), r.ravel(), roll_deg=r.ravel()))
    grid = resample(m, [np.pi / 2], MODEL_ROLL, [8e9, 12e9])
    assert np.flatnonzero(grid.mask[0]).tolist() == [0, 1, 15]
    np.testing.assert_allclose(grid.db[0, [0, 1, 15], 0], [0.0, 22.5, -22.5])  # the value is the roll in deg


def test_nothing_covered_is_an_error(tmp_path):
    m = read_csv(aspect_only_csv(tmp_path, [100.0], [8.0, 12.0]))
    with pytest.raises(UserInputError, match="no cell of the model's grid is covered"):
        resample(m, np.radians([0.0, 45.0]), [0.0], MODEL_FREQ, roll_symmetric=True)
