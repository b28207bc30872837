"""Speed of the PO simulator on a non-convex mesh, against the per-facet reference in the same run.

A 2,000-facet torus (1 m across), the default grid (32 aspects x 32 rolls x 64 frequencies,
8-12 GHz), shadowing on. Prints the best wall time of a few runs, facet-direction-frequency
evaluations per second, and the speed-up over tests/radar/po_reference.py, which is timed on a
few directions (all facets, all frequencies) and extrapolated linearly to the full grid.
Target on 2 cores: <= 1.0 s and >= 50x. ``--profile N`` also prints the N functions with the
most own time in one extra run (cProfile; Cython calls such as Embree's count in their caller).
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "radar"))

from po_reference import reference_po  # noqa: E402

from radar2shape.radar import RadarGrid, simulate  # noqa: E402
from radar2shape.radar import simulator  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--reference-directions", type=int, default=4)
    parser.add_argument("--profile", type=int, default=0, metavar="N", help="print the N top functions by own time")
    parser.add_argument("--chunks", type=int, nargs="*", default=[2**16, 2**17, 2**18], metavar="ENTRIES",
                        help="also time these simulator chunk sizes (facet-direction pairs per chunk), "
                             "interleaved in one run so that a drifting machine speed cancels")
    args = parser.parse_args()

    mesh = trimesh.creation.torus(0.35, 0.15, major_sections=50, minor_sections=20)
    grid = RadarGrid.default()
    n_dir = len(grid.aspect_rad) * len(grid.roll_rad)
    evals = len(mesh.faces) * n_dir * len(grid.freq_hz)
    simulate(mesh, grid.aspect_rad[:2], grid.roll_rad[:2], grid.freq_hz)  # warm-up (imports, caches)

    walls, cpus = [], []
    for _ in range(args.repeats):
        cpu, wall = time.process_time(), time.perf_counter()
        response = simulate(mesh, grid.aspect_rad, grid.roll_rad, grid.freq_hz, shadowing=True)
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    best = min(walls)

    rng = np.random.default_rng(0)
    picks = rng.choice(n_dir, size=args.reference_directions, replace=False)
    ia, ir = np.unravel_index(picks, (len(grid.aspect_rad), len(grid.roll_rad)))
    start = time.perf_counter()
    ref = np.stack([reference_po(mesh.vertices, mesh.faces, [grid.aspect_rad[a]], [grid.roll_rad[r]], grid.freq_hz)[0, 0]
                    for a, r in zip(ia, ir)])
    ref_total = (time.perf_counter() - start) / len(picks) * n_dir
    err = np.abs(response[ia, ir] - ref).max() / np.abs(ref).max()

    print(f"mesh: torus, {len(mesh.faces)} facets, non-convex; grid {grid.shape} (aspect, roll, freq), shadowing on")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine load average {load:.1f} on {os.cpu_count()} cores (wall times need an otherwise idle machine)")
    print(f"threads: {simulator.worker_count()}; wall time: best {best:.3f} s of {args.repeats} "
          f"(all: {', '.join(f'{w:.3f}' for w in walls)}); CPU time {min(cpus):.3f} s")
    print(f"evaluations (facet x direction x frequency): {evals:.3e}, {evals / best:.3e} per second")
    print(f"reference: {ref_total:.1f} s extrapolated from {len(picks)} directions x all facets x all frequencies")
    print(f"speed-up over the reference: {ref_total / best:.0f}x; max relative difference on those directions {err:.1e}")
    print(f"target (2 cores): <= 1.0 s and >= 50x -> {'met' if best <= 1.0 and ref_total / best >= 50 else 'NOT met'}")
    if args.chunks:
        chunk_times: dict[int, list[float]] = {n: [] for n in args.chunks}
        default = simulator.CHUNK_ENTRIES
        for _ in range(args.repeats):
            for n in args.chunks:
                simulator.CHUNK_ENTRIES = n
                wall = time.perf_counter()
                simulate(mesh, grid.aspect_rad, grid.roll_rad, grid.freq_hz, shadowing=True)
                chunk_times[n].append(time.perf_counter() - wall)
        simulator.CHUNK_ENTRIES = default
        print("chunk size (interleaved runs): " + "; ".join(
            f"{n}{' (default)' if n == default else ''}: best {min(t):.3f} s, median {np.median(t):.3f} s"
            for n, t in chunk_times.items()))
    if args.profile:
        profiler = cProfile.Profile()
        profiler.runcall(simulate, mesh, grid.aspect_rad, grid.roll_rad, grid.freq_hz, shadowing=True)
        pstats.Stats(profiler).sort_stats("tottime").print_stats(args.profile)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
