"""Cost of the equivalent edge currents against PO alone, in the same run.

A closed cylinder of 128 sections (512 faces, 256 sharp rim edges; radius 0.3 m, height 0.8 m) on
the default grid (32 aspects x 32 rolls x 64 frequencies, 8-12 GHz), shadowing on, one thread:
best of ``--repeats`` wall times for PO (VV), PO + edge currents (VV) and PO + edge currents with
all four polarisation channels, and the ratios to PO. Then a plate (0.3 x 0.2 m, 4 sheet edges, 2
facing pairs; 8 x 8 subdivided, 32 edge pieces per side pair) the same way, with single diffraction
(``edge_order=1``) beside the default that adds the double diffraction between facing edges.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import torch  # noqa: E402

from radar2shape.radar import RadarGrid, simulate  # noqa: E402
from radar2shape.radar.edge_pairs import sheet_pairs  # noqa: E402
from radar2shape.radar.edges import sharp_edges  # noqa: E402
from radar2shape.radar.facets import facet_mesh  # noqa: E402
from radar2shape.radar.validation import plate  # noqa: E402


def best_time(run, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    torch.set_num_threads(1)  # the simulator's chunk loop follows torch's thread count
    mesh = trimesh.creation.cylinder(radius=0.3, height=0.8, sections=128)
    grid = RadarGrid.default()
    axes = (grid.aspect_rad, grid.roll_rad, grid.freq_hz)
    edges = sharp_edges(facet_mesh(mesh))
    print(f"cylinder: {len(mesh.faces)} faces, {edges.n_edges} sharp edges; grid {len(axes[0])} x {len(axes[1])} x {len(axes[2])}")
    simulate(mesh, axes[0][:2], axes[1][:2], axes[2], method="po+ec")  # warm-up
    po = best_time(lambda: simulate(mesh, *axes), args.repeats)
    ec = best_time(lambda: simulate(mesh, *axes, method="po+ec"), args.repeats)
    ec_all = best_time(lambda: simulate(mesh, *axes, method="po+ec", polarization="all"), args.repeats)
    print(f"PO {po:.2f} s | PO+EC (VV) {ec:.2f} s ({ec / po:.1f}x PO) | PO+EC (all four) {ec_all:.2f} s ({ec_all / po:.1f}x PO)")
    sheet = plate(0.3, 0.2)
    for _ in range(3):
        sheet = trimesh.Trimesh(*trimesh.remesh.subdivide(sheet.vertices, sheet.faces), process=False)
    facets = facet_mesh(sheet)
    edges = sharp_edges(facets)
    pairs = sheet_pairs(edges, facets)
    print(f"plate: {len(sheet.faces)} faces, {edges.n_edges} sheet edges, {pairs.n_pairs} facing pairs")
    po = best_time(lambda: simulate(sheet, *axes, polarization="all"), args.repeats)
    single = best_time(lambda: simulate(sheet, *axes, method="po+ec", polarization="all", edge_order=1), args.repeats)
    double = best_time(lambda: simulate(sheet, *axes, method="po+ec", polarization="all"), args.repeats)
    print(f"PO {po:.2f} s | PO+EC single diffraction {single:.2f} s ({single / po:.1f}x PO) | "
          f"PO+EC with facing pairs {double:.2f} s ({double / po:.1f}x PO, {double / single:.2f}x single)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
