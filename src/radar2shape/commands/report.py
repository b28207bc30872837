"""``radar2shape report --grid NAME [--out DIR]``: a finished grid as the paper's Table 1.

Reads the runs of ``conf/grid/NAME.yaml`` (or a grid file path) from their folders, as
:mod:`radar2shape.sweep` left them, and writes to ``reports/NAME/`` (or ``--out``):

- ``NAME.md`` / ``NAME.csv``: rows = models, column groups = test conditions (observability,
  later test sets), cells ``mean ± std`` of Chamfer-L2 x10^3, volumetric IoU and F-score at 1 %,
  best of each column in bold (:mod:`radar2shape.reporting`), plus each run's wall time;
- ``NAME_<group>.png``: one row of reconstructions per model for the same test shapes, under a
  ground-truth row (the files the metric callback saved during ``test``).

Run names say where a run goes: ``<model>-<group>`` is the cell of row ``model`` in column group
``group`` (``radar2shape-full``, ``tmnet-partial``, ``radar2shape-full-sbr`` for PO-SBR test
data); a name without ``-`` is an auxiliary run (e.g. a Stage-1 VAE) listed with its wall time
only. Folders of ``out_dir`` named like a cell but not in the grid (a model scored by hand with
``radar2shape test --trainer.default_root_dir <out_dir>/<model>-<group>/test``, or written by
another experiment's script) are read from their logged test metrics and shown in a separate
table under the grid's: another protocol, never mixed into the grid's table, bold or CSV. A run
folder may hold a ``note`` file (one line, e.g. where a result was carried over from): it is
printed under the table, so no cell's origin is hidden.

Grids whose ``report:`` script is another one (``conf/grid/rollsym.yaml``: ``scripts/rollsym_table.py``,
the paper's Table 2 layout) are handed to that script as ``python SCRIPT --grid FILE [--out DIR]``,
the same call the sweep makes, so ``radar2shape report --grid NAME`` serves every grid.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from radar2shape.errors import UserInputError
from radar2shape.metrics.functional import metric_names
from radar2shape.reporting import Column, markdown_table, read_logged_metrics, write_csv

NAMES = metric_names()
COLUMNS = [
    Column(NAMES["chamfer"], "CD x10^3 ↓", higher_is_better=False, digits=2),
    Column(NAMES["iou"], "IoU ↑", higher_is_better=True),
    Column(NAMES["fscore"], "F-score@1% ↑", higher_is_better=True),
]
MODEL_TITLES = {
    "radar2shape": "Radar2Shape",
    "diffusion_sdf": "Diffusion-SDF",
    "tmnet": "TMNet",
    "list": "LIST",
    "nearest": "Nearest neighbour",
    "mean_shape": "Mean shape",
    "radar2shape_lora": "Radar2Shape + LoRA (PO-SBR fine-tuned)",
}
GROUP_TITLES = {
    "full": "full",
    "partial": "partial (70 % masked)",
    "full-sbr": "PO-SBR test, full",
    "partial-sbr": "PO-SBR test, partial",
}
FIGURE_SHAPES = 4


@dataclass
class Cell:
    """One finished (or missing) run of the grid."""

    name: str
    run_dir: Path
    state: str  # done | failed | missing | tested (outside the sweep)
    record: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--grid", required=True, help="grid name (conf/grid/NAME.yaml) or a grid YAML file")
    parser.add_argument("--out", help="output folder (default reports/NAME)")
    parser.add_argument("--shapes", type=int, default=FIGURE_SHAPES, help="test shapes per figure row")


def grid_path(name: str) -> Path:
    path = Path(name)
    return path if path.suffix in (".yaml", ".yml") else Path("conf/grid") / f"{name}.yaml"


def read_cell(name: str, run_dir: Path) -> Cell:
    """The state, ``done`` record and test metrics of one run folder."""
    if (run_dir / "done").is_file():
        metrics_file = run_dir / "metrics.json"
        metrics = json.loads(metrics_file.read_text()) if metrics_file.is_file() else {}
        return Cell(name, run_dir, "done", json.loads((run_dir / "done").read_text()), metrics)
    return Cell(name, run_dir, "failed" if (run_dir / "failed").is_file() else "missing")


def tested_cell(run_dir: Path) -> Cell | None:
    """A folder with a logged ``test`` but no sweep marker: its last test metrics, else None."""
    files = sorted(run_dir.glob("test/**/metrics.csv"), key=lambda p: p.stat().st_mtime)
    if not files:
        return None
    return Cell(run_dir.name, run_dir, "tested", {}, read_logged_metrics(files[-1]))


def collect_cells(grid) -> list[Cell]:
    """The grid's runs in file order, then cell-named folders of ``out_dir`` tested outside the grid."""
    cells = [read_cell(run.name, grid.run_dir(run)) for run in grid.runs]
    known = {cell.name for cell in cells}
    extra = sorted(p for p in grid.out_dir.glob("*-*") if p.is_dir() and p.name not in known) if grid.out_dir.is_dir() else []
    return cells + [cell for cell in map(tested_cell, extra) if cell is not None]


def split_name(name: str) -> tuple[str, str | None]:
    """``"tmnet-partial"`` -> ``("tmnet", "partial")``; an auxiliary run has no group."""
    model, _, group = name.partition("-")
    return model, group or None


def table_rows(cells: list[Cell]) -> tuple[list[tuple[str, dict]], list[Column], list[str]]:
    """Rows (model title, metrics keyed ``<group>/<metric>_mean|_std``), the grouped columns and the groups."""
    models: dict[str, dict] = {}
    groups: list[str] = []
    for cell in cells:
        model, group = split_name(cell.name)
        if group is None:
            continue
        groups += [group] if group not in groups else []
        row = models.setdefault(model, {})
        row.update({f"{group}/{key}": value for key, value in cell.metrics.items()})
    columns = [
        Column(f"{g}/{c.key}", f"{GROUP_TITLES.get(g, g)}: {c.header}", c.higher_is_better, c.digits)
        for g in groups for c in COLUMNS
    ]
    return [(MODEL_TITLES.get(m, m), metrics) for m, metrics in models.items()], columns, groups


def runs_table(cells: list[Cell]) -> str:
    """Markdown list of every run: state, command and wall time (fit + test)."""
    lines = ["| run | state | command | fit s | test s | wall s |", "|---|---|---|---|---|---|"]
    for cell in cells:
        r = cell.record
        command = r.get("command", "fit" if "fit_seconds" in r else "")
        lines.append(f"| {cell.name} | {cell.state} | {command} | {r.get('fit_seconds', '')} | {r.get('test_seconds', '')} | {r.get('wall_seconds', '')} |")
    total = sum(c.record.get("wall_seconds", 0.0) for c in cells)
    lines.append(f"| **total** | | | | | **{total:.0f}** |")
    return "\n".join(lines)


def run_notes(cells: list[Cell]) -> list[str]:
    """``- run: note`` for every run folder holding a ``note`` file."""
    notes = []
    for cell in cells:
        note = cell.run_dir / "note"
        if note.is_file():
            notes.append(f"- `{cell.name}`: {' '.join(note.read_text().split())}")
    return notes


def write_report(grid_file: Path, out: Path | None, n_shapes: int = FIGURE_SHAPES) -> Path:
    """Write the Markdown, CSV and figures of a grid; returns the Markdown file."""
    from radar2shape.sweep import load_grid

    grid = load_grid(grid_file)
    name = grid_file.stem
    out = Path(out) if out else Path("reports") / name
    out.mkdir(parents=True, exist_ok=True)
    cells = collect_cells(grid)
    in_grid, outside = cells[: len(grid.runs)], cells[len(grid.runs):]
    rows, columns, groups = table_rows(in_grid)
    write_csv(rows, columns, out / f"{name}.csv")
    figures = []
    for group in groups:
        group_cells = [c for c in in_grid if split_name(c.name)[1] == group and c.state == "done"]
        figure = save_figure(group_cells, out / f"{name}_{group}.png", n_shapes, GROUP_TITLES.get(group, group))
        figures += [figure] if figure else []
    text = [
        f"# {name}: reconstruction from radar",
        "",
        f"Grid `{grid_file}`, runs in `{grid.out_dir}`. Cells: mean ± std over the test set; Chamfer-L2 x10^3 "
        "(lower is better), volumetric IoU and F-score at 1 % of the unit cube (higher is better); "
        "best of each column in bold. `n/a`: run missing, failed, or the metric is undefined (IoU of point sets).",
        "",
        markdown_table(rows, columns),
        "",
    ]
    if outside:  # not the grid's test protocol, so never in its table, its bold or its CSV
        extra_rows, extra_columns, _ = table_rows(outside)
        text += [
            "Rows tested outside the grid (folders of the run directory that the grid does not list, e.g. "
            "written by another experiment's script; their test data and protocol are their own, so they "
            "are not compared with the table above):",
            "",
            markdown_table(extra_rows, extra_columns),
            "",
        ]
    notes = run_notes(cells)
    text += ["Notes on individual runs:", "", *notes, ""] if notes else []
    text += [
        "## Runs",
        "",
        runs_table(cells),
        "",
    ]
    text += [f"![{f.stem}]({f.name})\n" for f in figures]
    path = out / f"{name}.md"
    path.write_text("\n".join(text))
    return path


# ---- figure -----------------------------------------------------------------------------------
def saved_reconstructions(run_dir: Path) -> dict[int, Path]:
    """Test reconstructions the metric callback saved (``sample_<index>.obj|.ply``), by record index."""
    found = {}
    for path in sorted(run_dir.glob("test/**/reconstructions/test/epoch_*/sample_*")):
        if path.suffix in (".obj", ".ply"):
            found[int(path.stem.split("_")[1])] = path
    return found


def load_points(path: Path, n: int = 4096, seed: int = 0) -> np.ndarray:
    """Surface samples of a saved mesh, or the saved point set."""
    import trimesh

    from radar2shape.geometry.query import sample_surface

    loaded = trimesh.load(path, process=False)
    if isinstance(loaded, trimesh.Trimesh) and len(loaded.faces):
        return sample_surface(loaded, n, seed)[0]
    return np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))))


def ground_truth(run_dir: Path, indices: list[int]) -> dict[int, np.ndarray]:
    """``eval_points`` of test records by index, from the DataModule of the run's saved test config."""
    import importlib

    import yaml

    configs = sorted(run_dir.glob("test/**/config.yaml"))
    if not configs:
        return {}
    spec = yaml.safe_load(configs[-1].read_text()).get("data") or {}
    module, _, cls = str(spec.get("class_path", "")).rpartition(".")
    if not module:
        return {}
    datamodule = getattr(importlib.import_module(module), cls)(**(spec.get("init_args") or {}))
    datamodule.setup("test")
    wanted, found = set(indices), {}
    for batch in datamodule.test_dataloader():
        for i, points in zip(batch["index"].tolist(), batch["eval_points"].numpy()):
            if i in wanted:
                found[i] = points
        if len(found) == len(wanted):
            break
    return found


def save_figure(cells: list[Cell], path: Path, n_shapes: int, title: str) -> Path | None:
    """Ground truth, then one row per model, for the first ``n_shapes`` test shapes all runs saved."""
    from matplotlib.figure import Figure

    from radar2shape.metrics.render import VIEWS, depth_image

    saved = {c.name: saved_reconstructions(c.run_dir) for c in cells}
    indices = sorted(set().union(*saved.values()))[:n_shapes] if saved else []
    if not indices:
        return None
    rows = [("ground truth", ground_truth(cells[0].run_dir, indices))]
    rows += [(MODEL_TITLES.get(split_name(c.name)[0], c.name), {i: load_points(p) for i, p in saved[c.name].items()}) for c in cells]
    fig = Figure(figsize=(2.0 * len(indices) + 1.2, 2.0 * len(rows)))
    axes = fig.subplots(len(rows), len(indices), squeeze=False)
    for r, (label, points) in enumerate(rows):
        for c, index in enumerate(indices):
            ax = axes[r, c]
            image = depth_image(points[index], *VIEWS[0]) if index in points else np.full((2, 2), np.nan)
            ax.imshow(image, cmap="viridis", vmin=-0.6, vmax=0.6)
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(f"test #{index}", fontsize=9)
            if c == 0:
                ax.set_ylabel(label, fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path


def other_report_script(grid_file: Path) -> Path | None:
    """The grid's ``report:`` script when it is not this module (e.g. scripts/rollsym_table.py), else None."""
    from radar2shape.sweep import load_grid

    script = load_grid(grid_file).report
    if not script or Path(script).resolve() == Path(__file__).resolve():
        return None
    if not Path(script).is_file():
        raise UserInputError(f"{grid_file}: report script {script} not found")
    return Path(script)


def main(args: argparse.Namespace) -> int:
    grid_file = grid_path(args.grid)
    if not grid_file.is_file():
        raise UserInputError(f"--grid: {grid_file} not found (give a name under conf/grid/ or a grid YAML file)")
    script = other_report_script(grid_file)
    if script is not None:  # the grid's own layout (Table 2 for rollsym): the call the sweep makes
        command = [sys.executable, str(script), "--grid", str(grid_file)] + (["--out", str(args.out)] if args.out else [])
        return subprocess.run(command).returncode
    path = write_report(grid_file, args.out, args.shapes)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":  # a grid's `report:` script: python src/radar2shape/commands/report.py --grid FILE
    import sys

    from radar2shape.cli import run_tool

    sys.exit(run_tool("report", sys.argv[1:]))
