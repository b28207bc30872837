"""Why a Stage-1 ceiling is what it is: each test object's geometry beside its per-shape ceiling.

    python scripts/ceiling_geometry.py --data data/real \
        --scores reports/table1-real-long/scores/radar2shape_circ_steps12k-full-seed0.csv \
        --out reports/real/ceiling_geometry.md

For every test record (manifest order, the ``index`` column of a report's per-shape scores) this
measures three things and sets them beside the Stage-1 ceiling IoU of the scores file:

- *exact SDF meshed at R^3*: the record's own mesh, its exact signed distance on the evaluator's
  marching-cubes grid (R^3 over ``[-0.55, 0.55]^3``), meshed and scored like a reconstruction. At
  the test grid (64) it bounds any decoder; at a plane's resolution (32) it shows what survives
  when the shape is sampled no finer than the decoder's finest triplane.
- *thin share*: the share of the object's volume (its inside occupancy points) lying within
  ``--thin`` of its surface (default half a cell of a 32 px plane over 1.1: 0.0177). Near 1: the
  object is thinner than one plane cell nearly everywhere (wings, sheets, shells).
- the repair step of the record (as-is, fixed, union, remeshed).

Writes ``OUT`` (per-class table, Spearman correlations with the ceiling) and ``OUT`` with ``.csv``
(one row per shape). Bad input is one ``error:`` line.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import sys
from pathlib import Path

import numpy as np
import trimesh

from data_modules.manifest import read_manifest
from data_modules.records import read_record, record_path
from radar2shape.atomic import write_text_atomic
from radar2shape.errors import UserInputError
from radar2shape.geometry.query import unsigned_distance
from radar2shape.geometry.repair import remesh
from radar2shape.metrics.scoring import score_reconstruction
from radar2shape.reconstruction import Reconstruction
from radar2shape.reporting import read_scores

KEYS = ["vertices", "faces", "eval_points", "occ_points", "occ_inside", "provenance", "label"]


def thin_share(mesh: trimesh.Trimesh, occ_points: np.ndarray, occ_inside: np.ndarray, thin: float) -> float:
    """Share of the inside occupancy points within ``thin`` of the surface (nan for an empty solid)."""
    inside = occ_points[occ_inside].astype(np.float64)
    if len(inside) == 0:
        return math.nan
    return float(np.mean(unsigned_distance(mesh, inside) < thin))


def exact_sdf_scores(mesh: trimesh.Trimesh, record: dict, resolution: int) -> dict[str, float]:
    """IoU and F-score of the record's exact SDF meshed on a ``resolution``^3 grid.

    ``remesh`` works in the mesh's own normalised frame, which for a record (already centred,
    longest side 1) is the decoder's cube, so its grid is the evaluator's grid."""
    meshed = remesh(mesh, resolution)
    row = score_reconstruction(Reconstruction(mesh=meshed), record["eval_points"],
                               record["occ_points"], record["occ_inside"])
    return {"iou": row["iou"], "fscore_1pct": row["fscore_1pct"]}


def measure(root: Path, split: str, ids: list[str], resolutions: list[int], thin: float) -> list[dict]:
    rows = []
    for index, record_id in enumerate(ids):
        path = record_path(root, split, record_id)
        record = read_record(path, KEYS)
        mesh = trimesh.Trimesh(record["vertices"], record["faces"], process=False)
        row = {"index": index, "record_id": record_id, "label": int(record["label"]),
               "repair": json.loads(str(record["provenance"])).get("repair", "n/a"),
               "volume_share": float(np.mean(record["occ_inside"])),
               "thin_share": thin_share(mesh, record["occ_points"], record["occ_inside"], thin)}
        for r in resolutions:
            scores = exact_sdf_scores(mesh, record, r)
            row[f"exact{r}_iou"], row[f"exact{r}_fscore_1pct"] = scores["iou"], scores["fscore_1pct"]
        rows.append(row)
        print(f"\r{index + 1}/{len(ids)} records", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    return rows


def spearman(a: list[float], b: list[float]) -> tuple[float, int]:
    from scipy.stats import spearmanr
    pairs = [(x, y) for x, y in zip(a, b) if not (math.isnan(x) or math.isnan(y))]
    return float(spearmanr(*zip(*pairs)).statistic), len(pairs)


def mean(values: list[float]) -> float:
    values = [v for v in values if not math.isnan(v)]
    return sum(values) / len(values) if values else math.nan


def markdown(args, rows: list[dict], classes: list[str], columns: list[str]) -> str:
    titles = {"ceiling_iou": "Stage-1 ceiling IoU", "thin_share": "thin share", "volume_share": "volume share"}
    titles.update({c: f"exact SDF at {c[5:].split('_')[0]}^3: {'IoU' if c.endswith('iou') else 'F@1%'}"
                   for c in columns if c.startswith("exact")})
    shown = ["ceiling_iou"] + [c for c in columns if c.startswith("exact")] + ["thin_share", "volume_share"]
    lines = [f"# Stage-1 ceiling against geometry: `{args.data}`, {args.split} split", "",
             f"Made by `scripts/ceiling_geometry.py` from `{args.scores}` (per-shape Stage-1 ceilings) and the records' "
             f"meshes. Exact SDF at R^3: the true shape meshed on the evaluator's grid, a bound on any decoder at that "
             f"grid. Thin share: share of the object's volume within {args.thin:g} of its surface. Means per class:", "",
             "| class (shapes) | " + " | ".join(titles[c] for c in shown) + " |", "|---" * (len(shown) + 1) + "|"]
    def table_rows(key) -> list[str]:
        groups: dict[str, list[dict]] = {}
        for row in rows:
            groups.setdefault(key(row), []).append(row)
        return [f"| {name} ({len(members)}) | " + " | ".join(f"{mean([m[c] for m in members]):.3f}" for c in shown) + " |"
                for name, members in groups.items()]

    lines += sorted(table_rows(lambda r: classes[r["label"]] if r["label"] < len(classes) else str(r["label"])))
    lines.append(f"| **all** ({len(rows)}) | " + " | ".join(f"{mean([r[c] for r in rows]):.3f}" for c in shown) + " |")
    lines += ["", "By repair step:", "", "| repair (shapes) | " + " | ".join(titles[c] for c in shown) + " |",
              "|---" * (len(shown) + 1) + "|", *sorted(table_rows(lambda r: r["repair"]))]
    lines += ["", "Spearman rank correlation with the per-shape Stage-1 ceiling IoU:", "",
              "| quantity | Spearman ρ | shapes |", "|---|---|---|"]
    for c in shown[1:]:
        rho, n = spearman([r[c] for r in rows], [r["ceiling_iou"] for r in rows])
        lines.append(f"| {titles[c]} | {rho:+.2f} | {n} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", required=True, type=Path, help="a built dataset (manifest.json, records/)")
    parser.add_argument("--scores", required=True, type=Path, help="a report's per-shape scores with a ceiling_iou column")
    parser.add_argument("--split", default="test")
    parser.add_argument("--resolutions", type=int, nargs="+", default=[32, 64])
    parser.add_argument("--thin", type=float, default=0.0177)
    parser.add_argument("--out", required=True, type=Path)
    args = parser.parse_args()
    try:
        manifest = read_manifest(args.data)
        ids = list(manifest["splits"].get(args.split, []))
        scores = {int(float(r["index"])): r for r in read_scores(args.scores)}
        if not ids:
            raise UserInputError(f"{args.data}: split {args.split!r} has no records")
        if any("ceiling_iou" not in r for r in scores.values()) or not scores:
            raise UserInputError(f"{args.scores}: no ceiling_iou column (expected a latent model's per-shape scores)")
        if set(scores) != set(range(len(ids))):
            raise UserInputError(f"{args.scores}: indices do not match the {len(ids)} records of split {args.split!r}")
        if args.thin <= 0 or any(r < 8 for r in args.resolutions):
            raise UserInputError("--thin must be > 0 and every --resolutions entry >= 8")
        rows = measure(args.data, args.split, ids, args.resolutions, args.thin)
    except UserInputError as err:
        raise SystemExit(f"error: {err}") from None
    for row in rows:
        row["ceiling_iou"] = float(scores[row["index"]]["ceiling_iou"])
    columns = list(rows[0])
    csv_path = args.out.with_suffix(".csv")
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_text_atomic(csv_path, table.getvalue())
    write_text_atomic(args.out, markdown(args, rows, manifest["classes"], columns))
    print(f"wrote {args.out} and {csv_path}")


if __name__ == "__main__":
    main()
