"""PO and PO + edge currents against the Austin RCS Benchmark Suite (shared/validation/austin-rcs).

Each data file holds rows (frequency Hz, theta deg, phi deg, RCS dBsm) for one frequency and
polarisation (``.H.`` = HH, phi-hat; ``.V.`` = VV, theta-hat); ``radar.measured.read_austin``
parses them (checked rows, named errors). The suite's error measure: with TH = max(ref_dB) - 80,
avg_err_dB = mean over phi of |max(sim_dB, TH) - max(ref_dB, TH)|.
Run ``python -m radar2shape.radar.validation [DIR] [--out FILE]`` for the tables in docs/radar.md
(``make validation`` writes reports/radar/validation.md).
"""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import trimesh

from radar2shape.atomic import write_text_atomic
from radar2shape.errors import UserInputError
from radar2shape.geometry.almond import ALMOND_LENGTH_M, nasa_almond
from radar2shape.radar.measured import read_austin
from radar2shape.radar.signal import to_db
from radar2shape.radar.simulator import simulate

INCH = 0.0254


@dataclass(frozen=True)
class Cut:
    """One data file: a phi cut at fixed theta and frequency."""

    name: str
    freq_hz: float
    theta_rad: float
    phi_rad: np.ndarray
    rcs_db: np.ndarray

    @property
    def polarization(self) -> str:
        """"HH" or "VV" from the file name's polarisation letter (``...fx3.H.txt``)."""
        letter = self.name.split(".")[-2].upper()
        if letter not in ("H", "V"):
            raise UserInputError(f"{self.name}: expected a polarisation letter H or V before '.txt', got {letter!r}")
        return letter * 2


def default_dir() -> Path:
    """$RADAR2SHAPE_VALIDATION or ../shared/validation beside the repository."""
    env = os.environ.get("RADAR2SHAPE_VALIDATION")
    return Path(env) if env else Path(__file__).resolve().parents[3].parent / "shared" / "validation"


def read_cut(path: Path) -> Cut:
    """One Austin file through the measured-data reader (``radar.measured.read_austin``): a phi cut."""
    m = read_austin(path)
    if len(m.freq_hz) != 1 or len(m.aspect_rad) != 1:
        raise UserInputError(f"{path}: expected one frequency and one theta, got {m.freq_hz} Hz and "
                             f"{np.degrees(m.aspect_rad)} deg")
    return Cut(Path(path).name, float(m.freq_hz[0]), float(m.aspect_rad[0]), m.roll_rad, m.db[0, :, 0])


def avg_err_db(sim_db: np.ndarray, ref_db: np.ndarray) -> float:
    """The suite's thresholded mean absolute dB error (threshold 80 dB below the reference peak)."""
    th = ref_db.max() - 80.0
    return float(np.mean(np.abs(np.maximum(sim_db, th) - np.maximum(ref_db, th))))


def sector_err_db(sim_db: np.ndarray, cut: Cut, centre_deg: float = 90.0, half_deg: float = 30.0) -> float:
    """Mean |dB difference| over phi within half_deg of centre_deg (default: the broadside lobe)."""
    sector = np.abs(np.degrees(cut.phi_rad) - centre_deg) <= half_deg
    return float(np.mean(np.abs(sim_db - cut.rcs_db)[sector]))


def simulate_cuts(mesh, cuts: list[Cut], method: str = "po", **options) -> list[np.ndarray]:
    """RCS in dBsm along each cut in its own polarisation; cuts sharing a frequency and theta
    share one simulation (both polarisations at once). ``options`` go to ``simulate``."""
    out: list[np.ndarray | None] = [None] * len(cuts)
    groups: dict[tuple[float, float], list[int]] = {}
    for i, cut in enumerate(cuts):
        groups.setdefault((cut.freq_hz, cut.theta_rad), []).append(i)
    for (freq, theta), members in groups.items():
        phi = np.unique(np.concatenate([cuts[i].phi_rad for i in members]))
        names = tuple(sorted({cuts[i].polarization for i in members}))
        response = simulate(mesh, [theta], phi, [freq], method=method, polarization=names, **options)[0, :, 0]
        rcs_db = to_db(response, floor_db=-200.0)  # [phi, polarisation]
        for i in members:
            out[i] = rcs_db[np.searchsorted(phi, cuts[i].phi_rad), names.index(cuts[i].polarization)]
    return out


def almond_cuts(folder: Path, freq_ghz: float | None = None) -> list[Cut]:
    """Every almond file as a cut of the 9.936 in almond, optionally only at one frequency.

    meas.m2 files were measured on a 2x almond at half the frequency and shifted by -10 log 4 dB
    (IIIA_Data_file_descriptor.pdf); electromagnetic scaling makes them the 9.936 in almond at
    twice the file's frequency, which is what their cut says.
    """
    cuts = []
    for path in sorted((folder / "austin-rcs" / "almond-IIIA").glob("*.txt")):
        cut = read_cut(path)
        if cut.name.startswith("meas.m2"):
            cut = replace(cut, freq_hz=2.0 * cut.freq_hz)
        if freq_ghz is None or abs(cut.freq_hz / 1e9 - freq_ghz) < 1e-6:
            cuts.append(cut)
    return cuts


def almond_table(folder: Path, mesh: trimesh.Trimesh | None = None, freq_ghz: float | None = None,
                 method: str = "po", **options) -> list[tuple[str, float, float, float]]:
    """(file, GHz for the 9.936 in almond, avg_err_dB, broadside 60-120 deg error) per almond file."""
    mesh = nasa_almond(ALMOND_LENGTH_M) if mesh is None else mesh
    cuts = almond_cuts(folder, freq_ghz)
    sims = simulate_cuts(mesh, cuts, method, **options)
    return [(cut.name, cut.freq_hz / 1e9, avg_err_db(sim, cut.rcs_db), sector_err_db(sim, cut))
            for cut, sim in zip(cuts, sims)]


def plate(width_m: float, length_m: float, normal_axis: int = 2, long_axis: int = 0) -> trimesh.Trimesh:
    """A zero-thickness plate centred at the origin, seen from both sides (two facets per side)."""
    corners = np.zeros((4, 3))
    short_axis = 3 - normal_axis - long_axis
    corners[:, long_axis] = np.array([-1, 1, 1, -1]) * length_m / 2
    corners[:, short_axis] = np.array([-1, -1, 1, 1]) * width_m / 2
    faces = np.array([[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]])
    return trimesh.Trimesh(corners, faces, process=False)


# (file tag, plate width in inches, plate normal axis, axis of the 7W/4 side). The sx1 cases lie
# in the z-y plane (normal x); their sidelobes put the 7W/4 side along y. The s1 case lies in
# the x-y plane, seen 10 deg above grazing, where PO does not apply (edge diffraction rules).
PLATES = [("sx1.f9", 6, 0, 1), ("sx1.f10", 6, 0, 1), ("sx1.fx1", 6, 0, 1), ("sx1.f11", 6, 0, 1), ("s1.f10", 4, 2, 0)]


def plate_table(folder: Path, method: str = "po", **options) -> list[tuple[str, float, float, float]]:
    """(file, GHz, avg_err_dB, broadside error dB) for the plate-IIA references (W x 7W/4)."""
    rows = []
    for tag, width_in, normal, long_axis in PLATES:
        cuts = [read_cut(folder / "austin-rcs" / "plate-IIA" / f"ref_rcs.II.A.{tag}.{pol}.txt") for pol in "HV"]
        mesh = plate(width_in * INCH, 1.75 * width_in * INCH, normal_axis=normal, long_axis=long_axis)
        for cut, sim in zip(cuts, simulate_cuts(mesh, cuts, method, **options)):
            rows.append((cut.name, cut.freq_hz / 1e9, avg_err_db(sim, cut.rcs_db), float(sim[0] - cut.rcs_db[0])))
    return rows


def tables(folder: Path) -> str:
    """The almond and plate tables (PO beside PO + EC) as markdown, for docs/radar.md."""
    lines = ["# PO and PO + edge currents against the Austin RCS Benchmark Suite", "",
             "Written by `python -m radar2shape.radar.validation --out FILE` (`make validation`).", "",
             f"## NASA almond ({nasa_almond(ALMOND_LENGTH_M).faces.shape[0]:,} faces), theta = 90 deg, "
             "phi = 0..180 deg (0 = nose-on)", "",
             "| file | f (GHz) | avg_err_dB PO | avg_err_dB PO+EC | broadside PO | broadside PO+EC |",
             "|---|---|---|---|---|---|"]
    po, ec = almond_table(folder), almond_table(folder, method="po+ec")
    for (name, freq, err, sector), (_, _, err_ec, sector_ec) in zip(po, ec):
        lines.append(f"| {name} | {freq:.3f} | {err:.2f} | {err_ec:.2f} | {sector:.2f} | {sector_ec:.2f} |")
    lines += ["", "## Plate IIA (full-wave references)", "",
              "PO+EC single: `edge_order=1` (single diffraction only); PO+EC: the default `edge_order=2`, "
              "which adds the double diffraction between facing plate edges.", "",
              "| file | f (GHz) | avg_err_dB PO | avg_err_dB PO+EC single | avg_err_dB PO+EC | "
              "sim - reference at phi = 0, PO+EC (dB) |",
              "|---|---|---|---|---|---|"]
    po, single, ec = plate_table(folder), plate_table(folder, "po+ec", edge_order=1), plate_table(folder, "po+ec")
    for (name, freq, err, _), (_, _, err_single, _), (_, _, err_ec, offset_ec) in zip(po, single, ec):
        lines.append(f"| {name} | {freq:.3f} | {err:.2f} | {err_single:.2f} | {err_ec:.2f} | {offset_ec:+.2f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", type=Path, default=default_dir())
    parser.add_argument("--out", type=Path, help="write the tables to this markdown file (else print them)")
    args = parser.parse_args(argv)
    if not (args.folder / "austin-rcs").is_dir():
        parser.exit(2, f"error: {args.folder}: expected the validation folder holding austin-rcs/\n")
    text = tables(args.folder)
    if args.out:
        write_text_atomic(args.out, text)
        print(f"wrote {args.out}")
    else:
        print(text, end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
