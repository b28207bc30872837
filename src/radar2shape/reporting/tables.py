"""Table formatting shared by every layout, so all reports read the same way: ``mean ± std`` per
cell and the best value of each column in bold; :class:`Layout` says how run names map onto rows,
column groups and sections.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from radar2shape.reporting.cells import Cell


@dataclass(frozen=True)
class Column:
    """A table column: the metric key (without split prefix), its header, and which way is better.

    A cell reads ``<key>_mean ± <key>_<spread>``: ``spread="std"`` (over shapes) or ``"se"`` (the
    standard error of a mean, for paired differences). With ``total`` set the cell is a count
    instead, ``<key>_count of <total>`` ("18 of 20": shapes that scored the metric, of those evaluated).
    """

    key: str
    header: str
    higher_is_better: bool
    digits: int = 3
    spread: str = "std"
    total: str | None = None

    def fields(self) -> tuple[str, str]:
        """The two metric keys behind a cell (and the CSV's two columns)."""
        return (f"{self.key}_count", self.total) if self.total else (f"{self.key}_mean", f"{self.key}_{self.spread}")


def _cell(mean: float | None, std: float | None, digits: int, bold: bool, seeds_std: float | None = None) -> str:
    if mean is None or math.isnan(mean):
        return "n/a"
    text = f"{mean:.{digits}f}" if std is None else f"{mean:.{digits}f} ± {std:.{digits}f}"
    text = f"**{text}**" if bold else text
    return text if seeds_std is None else f"{text} (seeds ± {seeds_std:.{digits}f})"


# ---- seed replicates -------------------------------------------------------------------------------
SEED_SUFFIX = re.compile(r"-seed(\d+)$")  # ``radar2shape-full-seed1``: replicate 1 of ``radar2shape-full``


def merge_seeds(replicates: list[dict[str, float]]) -> dict[str, float]:
    """One metrics dict from the same run trained with several seeds.

    ``<k>_mean``: mean over seeds, with ``<k>_seeds_std`` (std of the seed means, ddof 1) and
    ``<k>_seeds`` (how many); ``<k>_std`` (over shapes): the mean over seeds; ``<k>_se`` (standard
    error of a mean): that of the mean of the seed means, sqrt(sum se^2) / n; counts and totals: the
    smallest over seeds (every seed scores the same shapes). A single replicate is returned as is.
    """
    if len(replicates) == 1:
        return dict(replicates[0])
    merged: dict[str, float] = {}
    for key in {k for r in replicates for k in r}:
        values = [r[key] for r in replicates if key in r and not math.isnan(r[key])]
        if not values:
            merged[key] = math.nan
        elif key.endswith("_mean"):
            mean = sum(values) / len(values)
            merged[key] = mean
            base = key[: -len("_mean")]
            merged[f"{base}_seeds"] = float(len(values))
            if len(values) > 1:
                merged[f"{base}_seeds_std"] = math.sqrt(sum((v - mean) ** 2 for v in values) / (len(values) - 1))
        elif key.endswith("_se"):
            merged[key] = math.sqrt(sum(v * v for v in values)) / len(values)
        elif key.endswith("_std"):
            merged[key] = sum(values) / len(values)
        else:
            merged[key] = min(values)
    return merged


def markdown_table(rows: list[tuple[str, dict[str, float]]], columns: list[Column]) -> str:
    """Rows of (name, metrics) where metrics hold ``KEY_mean`` and ``KEY_std``; best per column in bold."""
    best: dict[str, float] = {}
    for column in (c for c in columns if not c.total):
        means = [m[f"{column.key}_mean"] for _, m in rows if not math.isnan(m.get(f"{column.key}_mean", math.nan))]
        if means:
            best[column.key] = max(means) if column.higher_is_better else min(means)
    lines = ["| model | " + " | ".join(c.header for c in columns) + " |", "|---" * (len(columns) + 1) + "|"]
    for name, metrics in rows:
        cells = []
        for column in columns:
            mean, std = (metrics.get(key) for key in column.fields())
            if column.total:
                cells.append("n/a" if mean is None or std is None else f"{mean:.0f} of {std:.0f}")
                continue
            bold = mean is not None and column.key in best and mean == best[column.key]
            cells.append(_cell(mean, std, column.digits, bold, metrics.get(f"{column.key}_seeds_std")))
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_csv(rows: list[tuple[str, dict[str, float]]], columns: list[Column], path: str | Path) -> None:
    """The same table as CSV (mean and spread, or count and total, in separate columns), written atomically."""
    path = Path(path)
    tmp = path.with_suffix(path.suffix + ".tmp")
    seeded = any(f"{c.key}_seeds_std" in m for _, m in rows for c in columns)
    keys = [key for c in columns for key in c.fields() + ((f"{c.key}_seeds_std", f"{c.key}_seeds") if seeded and not c.total else ())]
    with tmp.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["model"] + keys)
        for name, metrics in rows:
            writer.writerow([name] + [metrics.get(key, "") for key in keys])
    tmp.replace(path)


# ---- layouts -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Layout:
    """A report layout: table columns, how run names map onto the table, and the writer.

    ``parts`` names the ``-``-separated parts of a run name, from ``row`` (a table row), ``group``
    (a column group) and ``section`` (one table each); the last part takes the rest of the name
    (``radar2shape-full-sbr`` with ``("row", "group")`` is row ``radar2shape``, group ``full-sbr``).
    A name with fewer parts is an auxiliary run (e.g. a Stage-1 VAE): listed with its wall time only.
    A trailing ``-seed<k>`` marks a seed replicate: replicates of one name share a table row
    (:func:`merge_seeds`: mean over seeds, the spread over seeds beside the spread over shapes).
    """

    name: str
    columns: tuple[Column, ...]
    write: Callable  # write(grid, out: Path, layout, shapes: int, archive: Path) -> the main Markdown file
    parts: tuple[str, ...] = ("row", "group")
    row_titles: dict[str, str] = field(default_factory=dict)
    group_titles: dict[str, str] = field(default_factory=dict)
    section_title: Callable[[str], str] = str
    diagnostics: tuple[Column, ...] = ()  # a second table: radar dependence, ceiling, counts
    describe_group: Callable[[str, list], str] | None = None  # (group, its cells) -> title, e.g. from run configs

    def split(self, run_name: str) -> dict[str, str] | None:
        """``{"row": ..., "group": ..., ...}`` of a run name, or None for an auxiliary run."""
        values = SEED_SUFFIX.sub("", run_name).split("-", len(self.parts) - 1)
        return dict(zip(self.parts, values)) if len(values) == len(self.parts) else None

    def row_title(self, row: str) -> str:
        return self.row_titles.get(row, row)

    def group_title(self, group: str, cells: list[Cell]) -> str:
        if self.describe_group is not None:
            return self.describe_group(group, cells)
        return self.group_titles.get(group, group)

    def tables(self, cells: list[Cell], columns: tuple[Column, ...] | None = None
               ) -> list[tuple[str | None, list[tuple[str, dict]], list[Column]]]:
        """``(section, rows, columns)`` per section in run order; rows are ``(title, metrics)`` with
        metrics keyed ``<group>/<metric>_mean|_std`` (``<metric>_...`` in a layout without groups).
        ``columns``: default the layout's main columns (``self.diagnostics`` for the second table)."""
        chosen = self.columns if columns is None else columns
        sections: dict[str | None, dict] = {}  # section -> row -> {(group, seed): metrics}
        groups: dict[str | None, list[str]] = {}
        members: dict[str | None, list[Cell]] = {}
        for cell in cells:
            where = self.split(cell.name)
            if where is None:
                continue
            section, group = where.get("section"), where.get("group")
            rows = sections.setdefault(section, {})
            row = rows.setdefault(where["row"], {})
            section_groups = groups.setdefault(section, [])
            section_groups += [group] if group not in section_groups else []
            row.setdefault(group, []).append(cell.metrics)
            members.setdefault(group, []).append(cell)
        for section, rows in sections.items():  # seed replicates -> one metrics dict per row
            for name, by_group in rows.items():
                rows[name] = {f"{group}/{key}" if group is not None else key: value
                              for group, replicates in by_group.items() for key, value in merge_seeds(replicates).items()}
        out = []
        for section, rows in sections.items():
            columns = [replace(c, key=f"{g}/{c.key}", header=f"{self.group_title(g, members[g])}: {c.header}",
                               total=c.total and f"{g}/{c.total}")
                       if g is not None else c for g in groups[section] for c in chosen]
            out.append((section, [(self.row_title(r), metrics) for r, metrics in rows.items()], columns))
        return out


def read_table(path: Path) -> list[tuple[str, dict[str, float]]]:
    """A report's table CSV as ``(row title, {column: value})``; empty cells are left out (no value)."""
    rows = []
    with path.open(newline="") as handle:
        for row in csv.DictReader(handle):
            title = row.pop("model")
            rows.append((title, {k: float(v) for k, v in row.items() if v not in ("", None)}))
    return rows


def columns(groups: dict[str, str], metrics: list[tuple[str, str, bool, int, str]]) -> list[Column]:
    """Columns ``<group>/<metric>`` with headers ``<group title>: <metric header>``."""
    return [Column(f"{group}/{key}", f"{title}: {header}", better, digits, spread)
            for group, title in groups.items() for key, header, better, digits, spread in metrics]
