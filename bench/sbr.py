"""Speed of the SBR hybrid (PO first bounce + ray sum of bounces 2..5) against PO in the same run.

Same mesh and grid as bench/radar.py: a 2,000-facet torus (1 m across), 32 aspects x 32 rolls x
64 frequencies (8-12 GHz), shadowing on. SBR on the full grid is slow (one ray tube per
(lambda_min / R)^2 of the ~0.5 m bounding disk per direction), so by default it is timed on a
few aspect rows (all rolls, all frequencies, batched as in a full run) and extrapolated linearly to
the full grid; the ray count per direction is fixed, so the cost is linear in the directions.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from radar2shape.radar import RadarGrid, simulate  # noqa: E402
from radar2shape.radar.sbr import launch_offsets  # noqa: E402
from radar2shape.radar.simulator import worker_count  # noqa: E402


def torus() -> trimesh.Trimesh:
    """bench/radar.py's mesh (built the same way; that script imports test helpers at load time)."""
    return trimesh.creation.torus(0.35, 0.15, major_sections=50, minor_sections=20)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=2, help="aspect rows timed for SBR (0 = full grid)")
    parser.add_argument("--bounces", type=int, default=5)
    parser.add_argument("--rays-per-wavelength", type=float, default=8.0)
    args = parser.parse_args()

    mesh, grid = torus(), RadarGrid.default()
    n_a, n_r = len(grid.aspect_rad), len(grid.roll_rad)
    n_dir = n_a * n_r
    simulate(mesh, grid.aspect_rad[:2], grid.roll_rad[:2], grid.freq_hz)  # warm-up

    start = time.perf_counter()
    po_full = simulate(mesh, grid.aspect_rad, grid.roll_rad, grid.freq_hz)
    po_time = time.perf_counter() - start

    rows = np.arange(n_a)
    if args.rows > 0:  # evenly spread rows, poles excluded
        rows = np.linspace(0, n_a - 1, min(args.rows, n_a) + 2)[1:-1].round().astype(int)
    start = time.perf_counter()
    sbr = simulate(mesh, grid.aspect_rad[rows], grid.roll_rad, grid.freq_hz, method="sbr",
                   max_bounces=args.bounces, rays_per_wavelength=args.rays_per_wavelength)
    sbr_time = (time.perf_counter() - start) / len(rows) * n_a
    diff = 20 * np.log10(np.abs(sbr) / np.abs(po_full[rows]))
    radius = float(np.linalg.norm(mesh.vertices - mesh.bounds.mean(axis=0), axis=1).max())
    rays = len(launch_offsets(radius, 299_792_458.0 / grid.freq_hz.max() / args.rays_per_wavelength))

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"mesh: torus, {len(mesh.faces)} facets; grid {grid.shape} (aspect, roll, freq); shadowing on")
    print(f"machine load average {load:.1f} on {os.cpu_count()} cores; "
          f"threads {worker_count()} (PO only; SBR is one thread)")
    print(f"SBR: {args.bounces} bounces, {args.rays_per_wavelength:g} rays per wavelength at "
          f"{grid.freq_hz.max() / 1e9:g} GHz -> {rays} ray tubes per direction")
    print(f"PO  full grid: {po_time:.2f} s")
    how = "measured" if len(rows) == n_a else f"extrapolated from aspect rows {rows.tolist()} x {n_r} rolls"
    print(f"SBR full grid: {sbr_time:.1f} s ({how}); ratio SBR / PO = {sbr_time / po_time:.0f}x")
    print(f"SBR - PO on those directions: median |diff| {np.median(np.abs(diff)):.2f} dB, "
          f"max {np.abs(diff).max():.1f} dB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
