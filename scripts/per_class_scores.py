"""Mean score per class of several runs on the same test split: which objects each model gets right.

    python scripts/per_class_scores.py --data data/real --out reports/table1-real/per_class.md \
        --run "Radar2Shape" reports/table1-real/scores/radar2shape-full-seed0.csv \
        --run "Nearest neighbour" reports/table1-real/scores/nearest-full.csv

Each ``--run LABEL SCORES.csv`` is a per-shape score file of a report (``scores/<run>.csv``, one row
per test shape with its class ``label``); ``--data`` is the dataset whose manifest names the
classes. One table per metric: rows = classes (with the number of test shapes), columns = runs,
the best run of each class in bold; a table holds the runs whose file has its column, so a Stage-1
check's ceiling file (``scripts/stage1_fit_gap.py --scores``) joins the Stage-1 ceiling table only. Bad input is one ``error:`` line.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from radar2shape.atomic import write_text_atomic
from radar2shape.reporting import read_scores

METRICS = (("iou", "IoU ↑", True), ("fscore_1pct", "F-score@1% ↑", True), ("chamfer_l2_x1e3", "CD x10^3 ↓", False))
CEILING = "ceiling_iou"  # a latent model's per-shape Stage-1 ceiling (docs/metrics.md); a table when present


def class_means(rows: list[dict], metric: str) -> dict[int, tuple[float, int]]:
    """``{label: (mean over the class's shapes with a defined score, count)}``."""
    values: dict[int, list[float]] = {}
    for row in rows:
        value = float(row[metric])
        if not math.isnan(value):
            values.setdefault(int(float(row["label"])), []).append(value)
    return {label: (sum(v) / len(v), len(v)) for label, v in values.items()}


def table(runs: dict[str, list[dict]], classes: list[str], metric: str, header: str, higher: bool) -> str:
    means = {label: class_means(rows, metric) for label, rows in runs.items()}
    labels = sorted({c for m in means.values() for c in m})
    lines = [f"| class (test shapes) | {' | '.join(runs)} |", "|---" * (len(runs) + 1) + "|"]
    for c in labels:
        cells = {run: means[run].get(c) for run in runs}
        present = [v[0] for v in cells.values() if v is not None]
        best = (max if higher else min)(present) if present else None
        count = max(v[1] for v in cells.values() if v is not None)
        text = ["n/a" if v is None else (f"**{v[0]:.3f}**" if v[0] == best and len(present) > 1 else f"{v[0]:.3f}")
                for v in cells.values()]
        lines.append(f"| {classes[c] if c < len(classes) else c} ({count}) | {' | '.join(text)} |")
    return f"### {header}\n\n" + "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="dataset folder (its manifest names the classes)")
    parser.add_argument("--run", nargs=2, action="append", metavar=("LABEL", "SCORES_CSV"), required=True)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    manifest = args.data / "manifest.json"
    if not manifest.is_file():
        print(f"error: --data: {manifest} not found (a built dataset folder)", file=sys.stderr)
        return 2
    classes = list(json.loads(manifest.read_text())["classes"])
    runs = {}
    for label, path in args.run:
        if not Path(path).is_file():
            print(f"error: --run {label}: {path} not found (expected a per-shape score file)", file=sys.stderr)
            return 2
        runs[label] = read_scores(Path(path))
        if not any(key in (runs[label] or [{}])[0] for key in (*(m[0] for m in METRICS), CEILING)):
            print(f"error: --run {label}: {path} has none of the columns {[m[0] for m in METRICS] + [CEILING]}",
                  file=sys.stderr)
            return 2
    parts = [f"# Scores per class ({args.data.name}, test split)", "",
             "Mean over each class's test shapes; best run of a class in bold. Made by "
             "`scripts/per_class_scores.py` from the report's per-shape scores:", "",
             *(f"- {label}: `{path}`" for label, path in args.run), ""]
    ceiling = (CEILING, "Stage-1 ceiling IoU ↑ (latent models: their Stage 1 decoding the true shapes)", True)
    for key, header, higher in (*METRICS, ceiling):  # each table holds the runs whose file has its column
        having = {label: rows for label, rows in runs.items() if rows and key in rows[0]}
        if having:
            parts.append(table(having, classes, key, header, higher) + "\n")
    write_text_atomic(args.out, "\n".join(parts))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
