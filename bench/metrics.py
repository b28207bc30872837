"""Benchmark: seconds to score one prediction against one ground truth at the default sizes.

    python bench/metrics.py [--points 30000] [--occ-points 100000] [--repeats 3]

The pair is realistic: a ground truth built like the procedural families (manifold3d union of
boxes and cylinders, a few thousand faces) and a prediction as the implicit models produce it
(marching cubes of an SDF on a 64^3 grid, ~20k faces). Prints the per-sample time the callback
spends (prediction sampling, nearest-neighbour distances, prediction containment) and the extra
ground-truth work the CLI does (the callback reads it from the batch). Target: < 0.5 s per pair.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

import manifold3d  # noqa: E402
import numpy as np  # noqa: E402
import trimesh  # noqa: E402

from radar2shape.geometry.marching_cubes import grid_points, sdf_grid_to_mesh  # noqa: E402
from radar2shape.geometry.query import contains, sample_surface  # noqa: E402
from radar2shape.metrics.functional import (  # noqa: E402
    chamfer_from_distances,
    fscore_from_distances,
    occupancy_points,
    surface_distances,
)

BOXES = [((0.0, 0.0, 0.0), (0.8, 0.8, 0.1)), ((0.0, 0.35, 0.35), (0.8, 0.1, 0.7))]  # seat, back
LEGS = [(x, y) for x in (-0.35, 0.35) for y in (-0.35, 0.35)]  # cylinders r 0.04, z in [-0.5, 0]


def ground_truth() -> trimesh.Trimesh:
    shape = manifold3d.Manifold()
    for centre, size in BOXES:
        shape += manifold3d.Manifold.cube(size, center=True).translate(centre)
    for x, y in LEGS:
        shape += manifold3d.Manifold.cylinder(0.5, 0.04, 0.04, 64, center=True).translate([x, y, -0.25])
    mesh = shape.to_mesh()
    return trimesh.Trimesh(mesh.vert_properties[:, :3], mesh.tri_verts)


def prediction(resolution: int = 64) -> trimesh.Trimesh:
    """Marching cubes of the same chair's analytic SDF with a small wobble: a good prediction."""
    p = grid_points(resolution).astype(np.float64)
    sdf = np.full(len(p), np.inf)
    for centre, size in BOXES:
        q = np.abs(p - centre) - np.asarray(size) / 2
        sdf = np.minimum(sdf, np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0))
    for x, y in LEGS:
        radial = np.hypot(p[:, 0] - x, p[:, 1] - y) - 0.04
        height = np.abs(p[:, 2] + 0.25) - 0.25
        outside = np.hypot(np.maximum(radial, 0), np.maximum(height, 0))
        sdf = np.minimum(sdf, outside + np.minimum(np.maximum(radial, height), 0))
    sdf += 0.004 * np.sin(20 * p[:, 0]) * np.sin(17 * p[:, 1])
    return sdf_grid_to_mesh(sdf.reshape((resolution,) * 3))


def time_pair(gt: trimesh.Trimesh, pred: trimesh.Trimesh, n_points: int, n_occ: int):
    """Per-part (wall, cpu) seconds and the scores (chamfer x 10^3, IoU, F-score)."""
    times: dict[str, tuple[float, float]] = {}

    def timed(name, fn, *args):
        start, cpu = time.perf_counter(), time.process_time()
        out = fn(*args)
        times[name] = (time.perf_counter() - start, time.process_time() - cpu)
        return out

    gt_points, _ = timed("cli: gt surface sampling", sample_surface, gt, n_points, 1)
    occ = timed("cli: occupancy points", occupancy_points, n_occ, 2)
    gt_inside = timed("cli: gt containment", contains, gt, occ)
    pred_points, _ = timed("pred surface sampling", sample_surface, pred, n_points, 0)
    distances = timed("nearest-neighbour distances", surface_distances, pred_points, gt_points)
    pred_inside = timed("pred containment", contains, pred, occ)
    chamfer = chamfer_from_distances(distances) * 1e3
    f = fscore_from_distances(distances)
    iou = np.count_nonzero(pred_inside & gt_inside) / np.count_nonzero(pred_inside | gt_inside)
    return times, (chamfer, iou, f)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=30_000)
    parser.add_argument("--occ-points", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    gt, pred = ground_truth(), prediction()
    time_pair(gt, pred, 1000, 1000)  # warm-up: imports, Embree and KD-tree code paths
    runs, scores = zip(*(time_pair(gt, pred, args.points, args.occ_points) for _ in range(args.repeats)))
    chamfer, iou, f = scores[0]
    best = {name: min(run[name] for run in runs) for name in runs[0]}  # least disturbed run
    callback = np.sum([v for k, v in best.items() if not k.startswith("cli")], axis=0)
    print(f"metrics, one pair (gt {len(gt.faces)} faces, pred {len(pred.faces)} faces, "
          f"{args.points} surface / {args.occ_points} occupancy points, best of {args.repeats}; "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores):")
    print(f"  {'part':<30} {'wall':>9} {'cpu':>9}")
    for name, (wall, cpu) in best.items():
        print(f"  {name:<30} {wall * 1e3:6.1f} ms {cpu * 1e3:6.1f} ms")
    print(f"  {'callback per sample':<30} {callback[0] * 1e3:6.1f} ms {callback[1] * 1e3:6.1f} ms  (target < 500 ms wall)")
    total = np.sum(list(best.values()), axis=0)
    print(f"  {'cli per pair':<30} {total[0] * 1e3:6.1f} ms {total[1] * 1e3:6.1f} ms")
    print(f"  scores: chamfer_l2_x1e3 {chamfer:.4f}  iou {iou:.4f}  fscore_1pct {f:.4f}")


if __name__ == "__main__":
    main()
