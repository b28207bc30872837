"""Readable reports: the run folders of a grid -> Markdown/CSV tables and figures.

One place formats every table (demo, Table 1, Table 2, monocones), so they all read the same way:
``mean ± std`` per cell and the best value of each column in bold. A report *layout*
(:class:`Layout`, registered in :mod:`radar2shape.report_layouts`) says which columns a table has
and how run names map onto its rows, column groups and sections; :func:`write_report` is the one
entry point (``radar2shape report`` and the end of ``radar2shape sweep``).
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np


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


# ---- run folders ---------------------------------------------------------------------------------
@dataclass
class Cell:
    """One finished (or missing) run of a grid."""

    name: str
    run_dir: Path
    state: str  # done | failed | missing | tested (outside the sweep) | archived (scored from a report's kept scores)
    record: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)


SCORES_GLOB = "test/**/reconstructions/test/epoch_*/scores.csv"  # the evaluator's per-shape scores of a run
ARCHIVED = "archived"  # a run whose folder is gone, scored from the per-shape scores its report kept


def read_scores(path: Path) -> list[dict]:
    with Path(path).open(newline="") as handle:
        return list(csv.DictReader(handle))


def pooled(rows: list[dict], keys) -> dict[str, float]:
    """``<key>_mean|_std|_count`` (std ddof 0, as the evaluator) and ``_se`` of per-shape rows, ``num_shapes``."""
    out = {"num_shapes": float(len(rows))}
    for key in keys:
        values = np.array([float(r[key]) for r in rows if r.get(key) not in (None, "")], float)
        values = values[np.isfinite(values)]
        if len(values):
            out.update({f"{key}_mean": float(values.mean()), f"{key}_std": float(values.std()),
                        f"{key}_count": float(len(values)),
                        f"{key}_se": float(values.std(ddof=1) / math.sqrt(len(values))) if len(values) > 1 else math.nan})
    return out


def score_keys(rows: list[dict]) -> list[str]:
    """The metric columns of per-shape score rows (all but the record index and class label)."""
    return [k for k in (rows[0] if rows else {}) if k not in ("index", "label")]


def test_config(run_dir: Path) -> dict | None:
    """The ``data.init_args`` and ``class_path`` of a run's saved test config (None without one)."""
    import yaml

    configs = sorted(run_dir.glob("test/**/config.yaml"))
    if not configs:
        return None
    data = (yaml.safe_load(configs[-1].read_text()) or {}).get("data") or {}
    return {"class_path": str(data.get("class_path", "")), **(data.get("init_args") or {})}


POINT_COUNTS = ("num_eval_points", "num_pred_points", "num_occ_points")  # the metric sampling a test logged


def cell_test_config(cell: Cell) -> dict | None:
    """A run's test data config: from its folder, or for an archived run from what the report kept."""
    if cell.state == ARCHIVED:
        return cell.record.get("test_data")
    return test_config(cell.run_dir) if cell.run_dir != Path() else None


def provenance(cell: Cell) -> dict:
    """What a report keeps beside a run's per-shape scores (``scores/<run>.json``) so that the run
    reads the same once its folder is gone: its ``done`` record (command, wall times), the metric
    point counts and the test data config (what the mask hid)."""
    return {"record": {k: v for k, v in cell.record.items() if k not in ("scores", "test_data")},
            "metrics": {k: cell.metrics[k] for k in POINT_COUNTS if k in cell.metrics},
            "test_data": cell_test_config(cell)}


def read_cell(name: str, run_dir: Path, archive: Path | None = None) -> Cell:
    """The state, ``done`` record and test metrics of one run folder.

    A run without a folder whose per-shape scores ``archive/<name>.csv`` a previous report kept
    (runs/ lives on one machine, reports/ in the repository) is re-pooled from those scores: the
    same means, spreads and counts as its test; its record, point counts and test config come from
    ``archive/<name>.json`` where the report kept one (:func:`provenance`); figures cannot be redrawn.
    """
    if (run_dir / "done").is_file():
        metrics_file = run_dir / "metrics.json"
        metrics = json.loads(metrics_file.read_text()) if metrics_file.is_file() else {}
        return Cell(name, run_dir, "done", json.loads((run_dir / "done").read_text()), metrics)
    if (run_dir / "failed").is_file():
        return Cell(name, run_dir, "failed")
    kept = archive / f"{name}.csv" if archive is not None else None
    if kept is not None and kept.is_file() and not run_dir.exists():
        rows = read_scores(kept)
        side = kept.with_suffix(".json")
        kept_info = json.loads(side.read_text()) if side.is_file() else {}
        record = {**kept_info.get("record", {}), "test_data": kept_info.get("test_data"), "scores": str(kept)}
        return Cell(name, run_dir, ARCHIVED, record, {**pooled(rows, score_keys(rows)), **kept_info.get("metrics", {})})
    return Cell(name, run_dir, "missing")


def scores_file(cell: Cell) -> Path | None:
    """The per-shape test scores behind a finished or archived cell (None if it has none)."""
    if cell.state == ARCHIVED:
        return Path(cell.record["scores"])
    if cell.state != "done":
        return None
    files = sorted(cell.run_dir.glob(SCORES_GLOB), key=lambda p: p.stat().st_mtime)
    return files[-1] if files else None


def tested_cell(run_dir: Path) -> Cell | None:
    """A folder with a logged ``test`` but no sweep marker: its last test metrics, else None."""
    files = sorted(run_dir.glob("test/**/metrics.csv"), key=lambda p: p.stat().st_mtime)
    if not files:
        return None
    return Cell(run_dir.name, run_dir, "tested", {}, read_logged_metrics(files[-1]))


def collect_cells(grid, archive: Path | None = None) -> tuple[list[Cell], list[Cell]]:
    """The grid's runs in file order (archived ones from ``archive``, see :func:`read_cell`), and the
    ``a-b``-named folders of ``out_dir`` the grid does not list but that hold a logged test (a model
    scored by hand, or another experiment's rows)."""
    cells = [read_cell(run.name, grid.run_dir(run), archive) for run in grid.runs]
    known = {cell.name for cell in cells}
    extra = sorted(p for p in grid.out_dir.glob("*-*") if p.is_dir() and p.name not in known) if grid.out_dir.is_dir() else []
    return cells, [cell for cell in map(tested_cell, extra) if cell is not None]


def runs_table(cells: list[Cell]) -> str:
    """Markdown list of every run: state, command and wall time (fit + test), and a summary line."""
    lines = ["| run | state | command | fit s | test s | wall s |", "|---|---|---|---|---|---|"]
    for cell in cells:
        r = cell.record
        command = r.get("command", "fit" if "fit_seconds" in r else "")
        command += " (resumed: fit s of the last sitting)" if r.get("resumed_from") else ""
        lines.append(f"| {cell.name} | {cell.state} | {command} | {r.get('fit_seconds', '')} | {r.get('test_seconds', '')} | {r.get('wall_seconds', '')} |")
    total = sum(c.record.get("wall_seconds", 0.0) for c in cells)
    lines.append(f"| **total** | | | | | **{total:.0f}** |")
    swept = [c for c in cells if c.state != "tested"]
    done = sum(c.state == "done" for c in swept)
    archived = sum(c.state == ARCHIVED for c in swept)
    lines += ["", f"{done} of {len(swept)} runs finished; summed wall time of the runs {total / 60:.1f} min "
              "(fit + test, excluding the prepare steps)."]
    if archived:
        unknown = sum(c.state == ARCHIVED and "wall_seconds" not in c.record for c in swept)
        lines[-1] += (f" {archived} more scored from the per-shape scores an earlier report kept (state "
                      f"`{ARCHIVED}`: run folder not on this machine; its record as that report kept it"
                      + (f", wall time not known for {unknown}" if unknown else "") + ").")
    return "\n".join(lines)


def run_notes(cells: list[Cell]) -> list[str]:
    """``- run: note`` for every run folder holding a ``note`` file (where a result came from)."""
    notes = []
    for cell in cells:
        note = cell.run_dir / "note"
        if note.is_file():
            notes.append(f"- `{cell.name}`: {' '.join(note.read_text().split())}")
    return notes


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


def get_layout(name: str) -> Layout:
    from radar2shape.report_layouts import LAYOUTS

    if name not in LAYOUTS:
        from radar2shape.errors import UserInputError

        raise UserInputError(f"unknown report layout {name!r} (expected one of {sorted(LAYOUTS)})")
    return LAYOUTS[name]


def write_report(grid, out: str | Path | None = None, layout: str | None = None, shapes: int = 4) -> Path:
    """Write ``grid``'s report in ``layout`` (default: the grid's ``report``, else ``table1``) to
    ``out`` (default ``reports/<grid name>``); returns the main Markdown file.

    All or nothing: the layout writes into a hidden staging folder inside ``out`` and its files
    are moved into place only once every one is written, so a failed report changes no file.
    """
    import shutil
    import tempfile

    from radar2shape.atomic import check_output_dir
    from radar2shape.errors import UserInputError

    chosen = get_layout(layout or grid.report or "table1")
    out = Path(out) if out else Path("reports") / grid.name
    check_output_dir(out, "--out")
    archive = out / "scores"  # per-shape scores this report kept last time: they stand in for lost run folders
    ran = grid.out_dir.is_dir() and any(grid.out_dir.iterdir())
    if not ran and not (archive.is_dir() and any(archive.glob("*.csv"))):
        raise UserInputError(f"{grid.path}: no runs to report: out_dir {grid.out_dir} is missing or empty "
                             f"and {archive} holds no per-shape scores (run 'radar2shape sweep {grid.path}' first)")
    created = [folder for folder in (out, *out.parents) if not folder.exists()]
    out.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".report-", dir=out))
    try:
        main = chosen.write(grid, staging, chosen, shapes, archive)
        for path in sorted(p for p in staging.rglob("*") if p.is_file()):
            target = out / path.relative_to(staging)
            target.parent.mkdir(parents=True, exist_ok=True)
            path.replace(target)
        return out / main.relative_to(staging)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        for folder in created:  # deepest first; only the folders this call made, once empty again
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
