"""Which frame rule places a canonical reconstruction best in a heading that is not a whole roll step?

    python scripts/placement_variants.py --ckpt RUN/checkpoints/last.ckpt --data data/real --split val \
        --classes airliner "business jet" "light aircraft" fighter helicopter --yaw-deg 37 \
        --out reports/table1-real-front/placement_variants_val.md

For a model that learns some classes in their stored heading (``canonical_heading`` or
``canonical_classes``), each record of the named classes is turned about z, normalised and
simulated as ``scripts/yaw_check.py`` does, and reconstructed once; the canonical mesh and the turn
the PO search found are then placed four ways and each scored against the turned, normalised mesh:
``turned`` (about the origin, as it is), ``scaled`` (and scaled about the origin by the ratio of
longest sides: what :func:`radar2shape.geometry.normalise.turned_in_frame` does), ``re-centred``
(scaled about the centre of its own turned box, moved to the origin) and ``offset kept`` (re-centred,
then moved by its own box offset turned). Writes a Markdown table, per object and the means, with
each rule paired against ``turned``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

RULES = ("turned", "scaled", "re-centred", "offset kept")


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ckpt", type=Path, required=True, help="a RadarDiffusion checkpoint learned in a canonical heading")
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--split", default="test", choices=("train", "val", "test"))
    parser.add_argument("--classes", nargs="+", required=True)
    parser.add_argument("--yaw-deg", type=float, default=37.0)
    parser.add_argument("--out", type=Path, required=True)
    return parser.parse_args(argv)


def placements(vertices: np.ndarray, rotation: np.ndarray) -> dict[str, np.ndarray]:
    """The vertices of a canonical mesh placed by each of :data:`RULES` for ``rotation``."""
    vertices = np.asarray(vertices, dtype=np.float64)
    turned = vertices @ rotation.T
    ratio = np.ptp(vertices, axis=0).max() / np.ptp(turned, axis=0).max()
    box_centre = (turned.min(axis=0) + turned.max(axis=0)) / 2.0
    own_offset = rotation @ ((vertices.min(axis=0) + vertices.max(axis=0)) / 2.0)
    return {"turned": turned, "scaled": turned * ratio, "re-centred": (turned - box_centre) * ratio,
            "offset kept": (turned - box_centre + own_offset) * ratio}


def main(argv=None) -> int:
    args = parse_args(argv)
    import torch
    import trimesh

    import radar2shape.geometry.normalise as normalise_module
    import yaw_check
    from radar2shape.atomic import write_text_atomic
    from radar2shape.pretrained import load_model
    from radar2shape.reconstruction import Reconstruction

    torch.set_num_threads(2)
    model = load_model(args.ckpt)
    if not (model.hparams.get("canonical_heading") or model.hparams.get("canonical_classes")):
        print(f"error: --ckpt {args.ckpt}: the model learns no class in a canonical heading, so it places nothing",
              file=sys.stderr)
        return 2
    placed = {}
    rule_in_use = normalise_module.turned_in_frame

    def keep(mesh, rotation):  # the canonical mesh and the found turn, as place_in_heading hands them over
        placed["mesh"], placed["rotation"] = mesh, np.asarray(rotation, dtype=np.float64)
        return rule_in_use(mesh, rotation)

    normalise_module.turned_in_frame = keep
    records, picked = yaw_check.records_of(args.data, args.classes, args.split)
    start = time.perf_counter()
    rows = []
    for i, _ in picked:
        record = records[i]
        placed.clear()
        yaw_check.score_turn(model, record, args.yaw_deg)
        if not placed:  # an empty reconstruction is not placed: it scores 0 whatever the rule
            rows.append((records.record_ids[i], dict.fromkeys(RULES, 0.0)))
            continue
        score = yaw_check.scorer(yaw_check.turned(trimesh.Trimesh(record["vertices"], record["faces"], process=False),
                                                  args.yaw_deg))
        faces = placed["mesh"].faces[:, ::-1] if np.linalg.det(placed["rotation"]) < 0 else placed["mesh"].faces
        scores = {rule: score(Reconstruction(mesh=trimesh.Trimesh(v, faces, process=False)))["iou"]
                  for rule, v in placements(placed["mesh"].vertices, placed["rotation"]).items()}
        rows.append((records.record_ids[i], scores))
        print(f"{records.record_ids[i]}: " + ", ".join(f"{k} {v:.3f}" for k, v in scores.items()))
    iou = np.array([[s[rule] for rule in RULES] for _, s in rows])
    lines = [f"# Placing a canonical reconstruction: {args.ckpt}", "",
             f"{args.split.capitalize()} records of {', '.join(args.classes)} in `{args.data}`, turned {args.yaw_deg:g} "
             "degrees about z, normalised, simulated with every cell observed and reconstructed once; the canonical "
             "mesh placed in the found heading by each rule and scored (IoU) against the turned, normalised mesh "
             f"(`scripts/placement_variants.py`, {time.perf_counter() - start:.0f} s).", "",
             "| object | " + " | ".join(RULES) + " |", "|---" * (len(RULES) + 1) + "|"]
    lines += [f"| {rid} | " + " | ".join(f"{s[rule]:.3f}" for rule in RULES) + " |" for rid, s in rows]
    lines += ["| mean | " + " | ".join(f"{m:.3f}" for m in iou.mean(axis=0)) + " |", ""]
    for k, rule in enumerate(RULES[1:], start=1):
        lines.append(f"- {rule} minus turned, paired over {len(iou)} objects: IoU {yaw_check.paired(iou[:, k] - iou[:, 0])}")
    write_text_atomic(args.out, "\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
