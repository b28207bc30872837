"""Readable reports: test metrics of finished runs -> Markdown/CSV tables in the paper's layout.

One place formats every table (demo, Table 1, Table 2), so they all read the same way:
``mean ± std`` per cell and the best value of each column in bold.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Column:
    """A table column: the metric key (without split prefix), its header, and which way is better."""

    key: str
    header: str
    higher_is_better: bool
    digits: int = 3


def read_logged_metrics(metrics_csv: str | Path, prefix: str = "test/") -> dict[str, float]:
    """Last logged value of every ``prefix``-metric in a Lightning CSVLogger ``metrics.csv``."""
    path = Path(metrics_csv)
    if not path.is_file():
        raise FileNotFoundError(f"no metrics file at {path}; did the run finish its test step?")
    values: dict[str, float] = {}
    with path.open() as handle:
        for row in csv.DictReader(handle):
            for key, value in row.items():
                if key and key.startswith(prefix) and value not in (None, ""):
                    values[key[len(prefix):]] = float(value)
    return values


def _cell(mean: float | None, std: float | None, digits: int, bold: bool) -> str:
    if mean is None or math.isnan(mean):
        return "n/a"
    text = f"{mean:.{digits}f}" if std is None else f"{mean:.{digits}f} ± {std:.{digits}f}"
    return f"**{text}**" if bold else text


def markdown_table(rows: list[tuple[str, dict[str, float]]], columns: list[Column]) -> str:
    """Rows of (name, metrics) where metrics hold ``KEY_mean`` and ``KEY_std``; best per column in bold."""
    best: dict[str, float] = {}
    for column in columns:
        means = [m[f"{column.key}_mean"] for _, m in rows if not math.isnan(m.get(f"{column.key}_mean", math.nan))]
        if means:
            best[column.key] = max(means) if column.higher_is_better else min(means)
    lines = ["| model | " + " | ".join(c.header for c in columns) + " |", "|---" * (len(columns) + 1) + "|"]
    for name, metrics in rows:
        cells = []
        for column in columns:
            mean = metrics.get(f"{column.key}_mean")
            std = metrics.get(f"{column.key}_std")
            bold = mean is not None and column.key in best and mean == best[column.key]
            cells.append(_cell(mean, std, column.digits, bold))
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_csv(rows: list[tuple[str, dict[str, float]]], columns: list[Column], path: str | Path) -> None:
    """The same table as CSV (mean and std in separate columns), written atomically."""
    path = Path(path)
    tmp = path.with_suffix(path.suffix + ".tmp")
    with tmp.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["model"] + [f"{c.key}_{s}" for c in columns for s in ("mean", "std")])
        for name, metrics in rows:
            writer.writerow([name] + [metrics.get(f"{c.key}_{s}", "") for c in columns for s in ("mean", "std")])
    tmp.replace(path)
