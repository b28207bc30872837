"""Run folders -> :class:`Cell`: a run's state, ``done`` record and test metrics, read from its
folder or, once the folder is gone, from the per-shape scores and provenance a report kept.
"""

from __future__ import annotations

import csv
import json
import math
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


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
    A fit without a test comes back from its kept record alone (its fit time in the runs table).
    """
    if (run_dir / "done").is_file():
        metrics_file = run_dir / "metrics.json"
        metrics = json.loads(metrics_file.read_text()) if metrics_file.is_file() else {}
        return Cell(name, run_dir, "done", json.loads((run_dir / "done").read_text()), metrics)
    if (run_dir / "failed").is_file():
        return Cell(name, run_dir, "failed")
    if archive is None or run_dir.exists():
        return Cell(name, run_dir, "missing")
    kept, side = archive / f"{name}.csv", archive / f"{name}.json"
    kept_info = json.loads(side.read_text()) if side.is_file() else {}
    if kept.is_file():
        rows = read_scores(kept)
        record = {**kept_info.get("record", {}), "test_data": kept_info.get("test_data"), "scores": str(kept)}
        return Cell(name, run_dir, ARCHIVED, record, {**pooled(rows, score_keys(rows)), **kept_info.get("metrics", {})})
    if kept_info.get("record"):  # a fit without a test: its record (command, fit time) is all there is
        return Cell(name, run_dir, ARCHIVED, kept_info["record"])
    return Cell(name, run_dir, "missing")


def scores_file(cell: Cell) -> Path | None:
    """The per-shape test scores behind a finished or archived cell (None if it has none)."""
    if cell.state == ARCHIVED:
        return Path(cell.record["scores"]) if "scores" in cell.record else None
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


def copy_scores(cells: list[Cell], folder: Path) -> int:
    """Each finished or archived run's per-shape test scores as ``folder/<run>.csv``, with its
    :func:`provenance` as ``folder/<run>.json`` (a fit without a test: the record alone, so its fit
    time outlives its folder); returns how many score files."""
    copied = 0
    for cell in cells:
        if cell.state not in ("done", ARCHIVED):
            continue
        path = scores_file(cell)
        folder.mkdir(parents=True, exist_ok=True)
        if path is not None:
            shutil.copyfile(path, folder / f"{cell.name}.csv")
            copied += 1
        (folder / f"{cell.name}.json").write_text(json.dumps(provenance(cell), indent=1, sort_keys=True))
    return copied


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


def sampling_line(cells: list[Cell]) -> str:
    """Which point counts the shape metrics used, from the runs' logged counts."""
    used = {}
    for cell in cells:
        m = cell.metrics
        if "num_eval_points" in m or "num_occ_points" in m:
            key = (int(m.get("num_eval_points", 0)), int(m.get("num_pred_points", m.get("num_eval_points", 0))),
                   int(m.get("num_occ_points", 0)))
            used.setdefault(key, []).append(cell.name)
    if not used:
        return "Point counts: not logged by these runs."
    parts = [f"CD and F-score on {e:,} ground-truth and {p:,} predicted surface points, IoU on {o:,} occupancy points"
             + ("" if len(used) == 1 else f" ({', '.join(names)})") for (e, p, o), names in used.items()]
    return "Sampling: " + "; ".join(parts) + "."
