"""Paired differences of two runs' per-shape scores: is run A better than run B on the same shapes?

    python scripts/paired_scores.py --out reports/table1-medium/paired.md \
        --pair "tuned - paper, full" reports/table1-medium/scores/radar2shape-full-seed0.csv \
                                     reports/table1-medium/scores/radar2shape_paper-full.csv

Each ``--pair LABEL A.csv B.csv`` (per-shape score files of a report, ``scores/<run>.csv``) gives
one row per metric: the mean over shapes of A - B, its standard error, and the shapes paired (by
record ``index``; shapes with an undefined score in either run are left out of that metric). Two
runs' means over 100 shapes each with a std of 0.2 differ by noise of 0.03; pairing removes the
shape-to-shape spread the two runs share, so this is the test to read before calling a change
an improvement. ``--metrics`` picks the columns (default IoU, F-score, Chamfer; the profile models'
reports add ``iou_s``, ``match_s``, ``iou_r``).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from radar2shape.atomic import write_text_atomic
from radar2shape.reporting import pooled, read_scores as read_rows

METRICS = ("iou", "fscore_1pct", "chamfer_l2_x1e3")


def read_scores(path: Path, metrics: tuple[str, ...] = METRICS) -> dict[int, dict[str, float]]:
    """``{record index: {metric: value}}`` of one per-shape score file."""
    if not path.is_file():
        raise SystemExit(f"error: {path}: not found (expected a per-shape score file, scores/<run>.csv)")
    rows = read_rows(path)
    missing = [m for m in ("index", *metrics) if rows and m not in rows[0]]
    if not rows or missing:
        raise SystemExit(f"error: {path}: expected columns index, {', '.join(metrics)}; missing {missing or 'all rows'}")
    return {int(row["index"]): {m: float(row[m]) for m in metrics} for row in rows}


def paired(a: dict[int, dict[str, float]], b: dict[int, dict[str, float]], metric: str) -> tuple[float, float, int]:
    """Mean of ``a - b`` over shapes in both with the metric defined, its standard error, and the count
    (pooled as the report pools per-shape scores)."""
    stats = pooled([{metric: a[i][metric] - b[i][metric]} for i in sorted(set(a) & set(b))], [metric])
    return stats.get(f"{metric}_mean", math.nan), stats.get(f"{metric}_se", math.nan), int(stats.get(f"{metric}_count", 0))


def report(pairs: list[tuple[str, Path, Path]], metrics: tuple[str, ...] = METRICS) -> str:
    lines = ["# Paired differences of per-shape scores", "",
             "Mean over shapes of A - B ± standard error (scripts/paired_scores.py); IoU (also IoU-S, IoU-R) and "
             "F-score: higher is better, Chamfer x10^3 and MATCH-S: lower is better.", "",
             "| A - B | A | B | metric | mean difference | shapes |", "|---|---|---|---|---|---|"]
    for label, path_a, path_b in pairs:
        a, b = read_scores(path_a, metrics), read_scores(path_b, metrics)
        for metric in metrics:
            mean, se, n = paired(a, b, metric)
            lines.append(f"| {label} | `{path_a}` | `{path_b}` | {metric} | {mean:+.4f} ± {se:.4f} | {n} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pair", nargs=3, action="append", required=True, metavar=("LABEL", "A", "B"))
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--metrics", nargs="+", default=list(METRICS), help="score-file columns to pair")
    args = parser.parse_args()
    text = report([(label, Path(a), Path(b)) for label, a, b in args.pair], tuple(args.metrics))
    write_text_atomic(args.out, text)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
