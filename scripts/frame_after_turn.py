"""How much does the frame alone cost a shape that is right but left in its unturned frame?

    python scripts/frame_after_turn.py --data data/real \
        --classes airliner "business jet" "light aircraft" fighter helicopter --yaw-deg 37 \
        --out reports/real/frame_after_turn.md

A user's object is normalised in the heading it is seen in (bounding box centred, longest side 1,
as ``radar2shape simulate`` does). Turned about z, an object's bounding box changes: a long box
widens, a cross-shaped aircraft narrows, so the same object normalised in the new heading is larger
or smaller. A model that learns shapes in their stored heading and turns its reconstruction into the
found one must apply that change too. For each test record of the named classes this script scores
the record's own mesh, turned but left at its unturned scale and centre, against the mesh turned and
normalised (`scripts/yaw_check.py`'s target): the IoU a perfect reconstruction would get without the
change. Writes a Markdown table (the ratio of normalised sizes and that IoU per object, the means).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="the dataset whose test split is turned")
    parser.add_argument("--classes", nargs="+", required=True)
    parser.add_argument("--yaw-deg", type=float, nargs="+", default=[37.0])
    parser.add_argument("--out", type=Path, required=True)
    return parser.parse_args(argv)


def frame_cost(mesh, yaw_deg: float) -> tuple[float, float]:
    """``(ratio, iou)``: the turned object's size normalised in its new heading over its unturned
    normalised size, and the IoU of the turned object left at its unturned scale and centre."""
    import trimesh

    from radar2shape.geometry.normalise import normalise
    from radar2shape.reconstruction import Reconstruction
    from yaw_check import scorer

    unturned = normalise(mesh)[0]
    left = unturned.copy()
    left.apply_transform(trimesh.transformations.rotation_matrix(math.radians(yaw_deg), (0, 0, 1)))
    target, _, scale = normalise(left)
    return float(scale), float(scorer(target)(Reconstruction(mesh=left))["iou"])


def main(argv=None) -> int:
    args = parse_args(argv)
    import trimesh

    from radar2shape.atomic import write_text_atomic
    from yaw_check import records_of

    records, picked = records_of(args.data, args.classes)
    start = time.perf_counter()
    rows = []
    for i, name in picked:
        mesh = trimesh.Trimesh(records[i]["vertices"], records[i]["faces"], process=False)
        rows.append((records.record_ids[i], name, [frame_cost(mesh, yaw) for yaw in args.yaw_deg]))
    header = " | ".join(f"size ratio at {y:g} deg | IoU left unscaled at {y:g} deg" for y in args.yaw_deg)
    lines = [f"# The frame after a turn: `{args.data}`", "",
             f"Test objects of {', '.join(args.classes)}, each turned about z: the size of the object normalised "
             "in the new heading over its unturned normalised size, and the IoU of the record's own mesh turned "
             "but left at its unturned scale and centre against the turned, normalised mesh "
             f"(`scripts/frame_after_turn.py`, {time.perf_counter() - start:.0f} s).", "",
             f"| object | class | {header} |", "|---" * (2 + 2 * len(args.yaw_deg)) + "|"]
    lines += [f"| {rid} | {name} | " + " | ".join(f"{r:.3f} | {iou:.3f}" for r, iou in costs) + " |"
              for rid, name, costs in rows]
    means = np.array([[v for cost in costs for v in cost] for _, _, costs in rows]).mean(axis=0)
    lines += ["| mean | | " + " | ".join(f"{m:.3f}" for m in means) + " |", ""]
    write_text_atomic(args.out, "\n".join(lines))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
