"""SBR hybrid (PO first bounce + ray sum of bounces 2..5): corner-reflector anchors and the torus.

``--suite anchors`` (default): the usual PO-SBR anchor cases, each over 901 angles at 3 GHz
(lambda = 10 cm), 5 bounces, shadowing on:

* plate: 1 m x 1 m square in the yz plane; aspect 90 deg, roll -90..90 deg (0.2 deg steps);
  boresight (roll 0) peak 4 pi A^2 / lambda^2;
* dihedral: two 1 m x 1 m plates at 90 degrees, fold along z; aspect 90 deg, roll 0..90 deg
  (0.1 deg steps); boresight (roll 45) peak 8 pi a^2 b^2 / lambda^2;
* trihedral: triangular, 1 m edges along x, y, z; aspect arccos(1/sqrt 3) (the symmetry axis),
  roll 0..90 deg (0.1 deg steps); boresight (roll 45) peak 4 pi a^4 / (3 lambda^2).

Each case is timed on one core (the process pinned to one CPU, so PO uses one thread and SBR
runs in-process) and on all the process's cores (SBR in worker processes, whose one-off
start-up is timed separately), and the two responses are compared. Peak memory is the
tracemalloc peak of a one-worker run over 19 angles around boresight (the batch memory does
not depend on the number of angles), at each ``--memory-densities`` value.

``--suite torus``: SBR against PO on bench/radar.py's mesh and grid (2,000-facet torus, 32 x 32
directions x 64 frequencies, 8-12 GHz), SBR timed on a few aspect rows and extrapolated.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tracemalloc
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from radar2shape.radar import RadarGrid, simulate, sbr  # noqa: E402
from radar2shape.radar.po import SPEED_OF_LIGHT  # noqa: E402
from radar2shape.radar.simulator import worker_count  # noqa: E402

FREQ_HZ = 3e9
LAM = SPEED_OF_LIGHT / FREQ_HZ


@dataclass(frozen=True)
class Case:
    name: str
    vertices: np.ndarray
    faces: np.ndarray
    aspect_deg: float
    roll_deg: np.ndarray  # 901 angles
    boresight: int  # index of the boresight angle in roll_deg
    theory_m2: float
    formula: str


def cases() -> list[Case]:
    plate_v = np.array([[0, -0.5, -0.5], [0, 0.5, -0.5], [0, 0.5, 0.5], [0, -0.5, 0.5]], dtype=float)
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    dihedral_v = np.array([[0, 0, -0.5], [1, 0, -0.5], [1, 0, 0.5], [0, 0, 0.5], [0, 1, -0.5], [0, 1, 0.5]],
                          dtype=float)
    trihedral_v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
    return [
        Case("plate 1 x 1 m", plate_v, quad, 90.0, np.linspace(-90, 90, 901), 450, 4 * np.pi / LAM**2,
             "4 pi A^2/lambda^2"),
        Case("dihedral 1 x 1 m", dihedral_v, np.array([[0, 1, 2], [0, 2, 3], [0, 3, 5], [0, 5, 4]]), 90.0,
             np.linspace(0, 90, 901), 450, 8 * np.pi / LAM**2, "8 pi a^2 b^2/lambda^2"),
        Case("trihedral a = 1 m", trihedral_v, np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1]]),
             float(np.degrees(np.arccos(1 / np.sqrt(3)))), np.linspace(0, 90, 901), 450,
             4 * np.pi / (3 * LAM**2), "4 pi a^4/(3 lambda^2)"),
    ]


def run_case(case: Case, roll_deg: np.ndarray, rays_per_wavelength: float) -> np.ndarray:
    s = simulate((case.vertices, case.faces), np.radians([case.aspect_deg]), np.radians(roll_deg), [FREQ_HZ],
                 method="sbr", rays_per_wavelength=rays_per_wavelength)
    return s[0, :, 0]


def timed(function, *args):
    start = time.perf_counter()
    out = function(*args)
    return time.perf_counter() - start, out


def db(x):
    return 10 * np.log10(x)


def peak_memory(case: Case, rays_per_wavelength: float) -> tuple[float, float]:
    """(tracemalloc peak in MiB of a run on 19 angles around boresight, boresight dB error).

    Called with the process pinned to one core, so the batches run in this process and the
    peak covers them (worker processes are outside tracemalloc's view).
    """
    near = case.roll_deg[case.boresight - 9:case.boresight + 10]
    tracemalloc.start()
    s = run_case(case, near, rays_per_wavelength)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20, db(abs(s[9]) ** 2 / case.theory_m2)


def anchors(args) -> None:
    cores = sorted(os.sched_getaffinity(0))
    print(f"anchor cases at {FREQ_HZ / 1e9:g} GHz (lambda {LAM * 100:.2f} cm), 901 angles, 5 bounces, "
          f"{args.rays_per_wavelength:g} rays per wavelength for the timings")
    print(f"cores available: {len(cores)} {cores}; load average {os.getloadavg()[0]:.2f} (1 min) at start"
          + ("" if len(cores) > 1 else " (one core: both timings below run on it)"))
    workers = worker_count()
    if workers > 1:  # start the kept worker pool outside the timings
        warm, _ = timed(lambda: list(sbr.map_batches(abs, [(i,) for i in range(workers)], workers)))
        print(f"SBR worker pool start-up (one-off per process, {workers} workers): {warm:.2f} s")
    rows = []
    for case in cases():
        t_all, s_all = timed(run_case, case, case.roll_deg, args.rays_per_wavelength)
        os.sched_setaffinity(0, cores[:1])  # one core: one PO thread, SBR in this process
        try:
            t_one, s_one = timed(run_case, case, case.roll_deg, args.rays_per_wavelength)
            memory = {rpw: peak_memory(case, rpw) for rpw in args.memory_densities}
        finally:
            os.sched_setaffinity(0, cores)
        diff = np.abs(s_all - s_one).max() / np.abs(s_one).max()
        err = db(abs(s_all[case.boresight]) ** 2 / case.theory_m2)
        rows.append((case, t_one, t_all, diff, err, memory))

    print()
    print(f"| case | theory (dBsm) | 1 core (s) | {len(cores)} cores (s) | speed-up | 1 vs {len(cores)} cores "
          f"max rel. diff | boresight error (dB) | "
          + " | ".join(f"peak memory {rpw:g} rays/lambda (MiB) / boresight error (dB)" for rpw in args.memory_densities)
          + " |")
    print("|---" * (7 + len(args.memory_densities)) + "|")
    for case, t_one, t_all, diff, err, memory in rows:
        mem = " | ".join(f"{m:.1f} / {e:+.3f}" for m, e in memory.values())
        print(f"| {case.name} ({case.formula}) | {db(case.theory_m2):.2f} | {t_one:.2f} | {t_all:.2f} | "
              f"{t_one / t_all:.2f}x | {diff:.1e} | {err:+.3f} | {mem} |")
    print(f"\nper-worker memory bound (sbr.memory_bound, default {sbr.DEFAULT_RAYS_PER_BATCH} rays per batch, "
          f"1 frequency): {sbr.memory_bound(sbr.DEFAULT_RAYS_PER_BATCH, 1) / 2**20:.0f} MiB")
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) at the end")


def torus_suite(args) -> None:
    mesh = trimesh.creation.torus(0.35, 0.15, major_sections=50, minor_sections=20)
    grid = RadarGrid.default()
    n_a, n_r = len(grid.aspect_rad), len(grid.roll_rad)
    simulate(mesh, grid.aspect_rad[:2], grid.roll_rad[:2], grid.freq_hz, method="sbr")  # warm-up, worker start-up

    po_time, po_full = timed(simulate, mesh, grid.aspect_rad, grid.roll_rad, grid.freq_hz)
    rows = np.arange(n_a)
    if args.rows > 0:  # evenly spread rows, poles excluded
        rows = np.linspace(0, n_a - 1, min(args.rows, n_a) + 2)[1:-1].round().astype(int)
    sbr_time, s = timed(lambda: simulate(mesh, grid.aspect_rad[rows], grid.roll_rad, grid.freq_hz, method="sbr",
                                         rays_per_wavelength=args.rays_per_wavelength))
    sbr_time *= n_a / len(rows)
    diff = 20 * np.log10(np.abs(s) / np.abs(po_full[rows]))
    print(f"mesh: torus, {len(mesh.faces)} facets; grid {grid.shape} (aspect, roll, freq); shadowing on")
    print(f"load average {os.getloadavg()[0]:.2f} on {len(os.sched_getaffinity(0))} usable cores; "
          f"workers/threads {worker_count()} (PO threads and SBR processes)")
    print(f"PO  full grid: {po_time:.2f} s")
    how = "measured" if len(rows) == n_a else f"extrapolated from aspect rows {rows.tolist()} x {n_r} rolls"
    print(f"SBR full grid ({args.rays_per_wavelength:g} rays per wavelength): {sbr_time:.1f} s ({how}); "
          f"ratio SBR / PO = {sbr_time / po_time:.0f}x")
    print(f"SBR - PO on those directions: median |diff| {np.median(np.abs(diff)):.2f} dB, "
          f"max {np.abs(diff).max():.1f} dB")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", choices=("anchors", "torus"), default="anchors")
    parser.add_argument("--rays-per-wavelength", type=float, default=4.0, help="density of the timed runs")
    parser.add_argument("--memory-densities", type=float, nargs="+", default=[4.0, 16.0])
    parser.add_argument("--rows", type=int, default=2, help="torus: aspect rows timed for SBR (0 = full grid)")
    args = parser.parse_args()
    if args.suite == "anchors":
        anchors(args)
    else:
        torus_suite(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
