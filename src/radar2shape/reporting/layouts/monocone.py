"""``monocone``: the zero-shot monocone experiment (``scripts/monocone_experiment.py`` leaves
per-target scores under ``<out_dir>/experiment/``), in Table 1's column layout.
"""

from __future__ import annotations

import csv
import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np

from radar2shape.reporting.cells import Cell, collect_cells, runs_table
from radar2shape.reporting.figures import depth_axis
from radar2shape.reporting.layouts.columns import IOU_S, MATCH_S, SHAPE_COLUMNS
from radar2shape.reporting.tables import Layout, markdown_table, write_csv


MONOCONE_SETTINGS = ("full", "partial")
MONOCONE_MODELS = {"radar2shape": "Radar2Shape (3D, roll repeated)", "unet": "Profile U-Net diffusion", "invrt": "InvRT"}
CONTROL = "_control"  # score rows of a model fed another target's radar
MONOCONE_FIGURE_TARGETS = 4


def _mean_std(values: list[float]) -> tuple[float, float]:
    v = np.asarray([x for x in values if np.isfinite(x)], float)
    return (float(v.mean()), float(v.std())) if len(v) else (float("nan"), float("nan"))


def monocone_cells(scores: list[dict], columns) -> list[Cell]:
    """Per-target scores -> one pseudo-run ``<model>-<setting>`` per model and setting (mean ± std)."""
    cells = {}
    for row in scores:
        cells.setdefault(f"{row['model']}-{row['setting']}", []).append(row)
    out = []
    for name, rows in cells.items():
        metrics = {}
        for column in columns:
            values = [float(r[column.key]) for r in rows]
            metrics[f"{column.key}_mean"], metrics[f"{column.key}_std"] = _mean_std(values)
            metrics[f"{column.key}_count"] = float(np.isfinite(values).sum())
        metrics["num_shapes"] = float(len(rows))
        out.append(Cell(name, Path(), "done", {}, metrics))
    return out


def write_monocone(grid, out: Path, layout: Layout, shapes: int, archive: Path | None = None) -> Path:
    """``monocone.md`` / ``monocone.csv`` (Table 1 columns), the paired radar-vs-control table,
    ``scores.csv`` and ``monocone_<setting>.png``, from ``<out_dir>/experiment/``."""
    work = grid.out_dir / "experiment"
    cells, _ = collect_cells(grid)
    lines = ["# Monoconic targets: zero-shot reconstruction from simulated measurements", ""]
    if not (work / "scores.csv").is_file():
        lines += [f"No scores under `{work}` yet: run `make monocone` (scripts/monocone_experiment.py).", "",
                  "## Runs", "", runs_table(cells), ""]
        (out / "monocone.md").write_text("\n".join(lines))
        return out / "monocone.md"
    with open(work / "scores.csv", newline="") as handle:
        scores = list(csv.DictReader(handle))
    shutil.copyfile(work / "scores.csv", out / "scores.csv")
    info = json.loads((work / "experiment.json").read_text())
    target_cells = monocone_cells(scores, layout.columns)
    (_, rows, columns), *_ = layout.tables(target_cells)
    write_csv(rows, columns, out / "monocone.csv")
    low, high = info["model_band_ghz"]
    size = info["size_m"]
    lines += [f"{info['targets']} blunted cones (`{info['data_config']}`), measured in simulation at {size:g} m length: PO, "
              f"aspect-only (roll 0), aspects 0-180 deg every {info['aspect_step_deg']:g} deg, {info['num_freq']} "
              f"frequencies over {low / size:g}-{high / size:g} GHz (= {low:g}-{high:g} GHz at the models' 1 m), "
              f"complex noise at {info['noise_db']:g} dBsm (1 m scale), written as generic CSV and read back through "
              f"`radar.measured` with `--size-m {size:g}`. Partial: one contiguous aspect window keeping "
              f"{100 * info['keep']:.0f} % of the aspects, the other rows absent (masked on the model grid). "
              "No model saw a monocone in training (zero-shot): the 3D model was trained on a `parts` set, the "
              "profile models on a `frusta` set (the checkpoints below say which runs).", "",
              "Cells: mean ± std over the targets, best of each column in bold. CD = Chamfer-L2 x10^3, IoU volumetric, "
              "F-score at 1 % of the unit cube; IoU-S / MATCH-S compare the half cross-sections (docs/rollsym.md; a 3D "
              "mesh that is not a solid of revolution scores IoU-S 0 and no MATCH-S). Control rows: each target "
              "reconstructed from the next target's radar.", "",
              markdown_table(rows, columns), "",
              "Targets scored (a metric is undefined for a target whose prediction has no valid surface or profile):", "",
              markdown_table(*layout.tables(target_cells,
                                            tuple(replace(c, header=f"n {c.header.split(' ')[0]}", total="num_shapes")
                                                  for c in layout.columns))[0][1:]), "",
              "## Does the radar matter? (real minus control, paired over targets)", "",
              "Each target scored with the reconstruction from its own radar minus the reconstruction from the next "
              "target's radar: mean ± standard error of the paired differences. Near zero = the output hardly "
              "depends on the input radar.", "",
              "| model | full: Δ IoU | full: Δ IoU-S | partial: Δ IoU | partial: Δ IoU-S |", "|---|---|---|---|---|"]
    models = list(dict.fromkeys(r["model"] for r in scores if not r["model"].endswith(CONTROL)))
    for model in models:
        cells_text = [MONOCONE_MODELS.get(model, model)]
        for setting in MONOCONE_SETTINGS:
            for key in ("iou", "iou_s"):
                real = {r["target"]: float(r[key]) for r in scores if r["model"] == model and r["setting"] == setting}
                control = {r["target"]: float(r[key]) for r in scores if r["model"] == model + CONTROL and r["setting"] == setting}
                diff = np.array([real[t] - control[t] for t in real if t in control])
                cells_text.append(f"{diff.mean():+.3f} ± {diff.std(ddof=1) / np.sqrt(len(diff)):.3f}" if len(diff) > 1 else "n/a")
        lines.append("| " + " | ".join(cells_text) + " |")
    lines += ["", "## Checkpoints", "", "| model | full | partial |", "|---|---|---|"]
    lines += [f"| {MONOCONE_MODELS.get(m, m)} | `{c['full']}` | `{c['partial']}` |" for m, c in info["checkpoints"].items()]
    surfaces = np.load(work / "surfaces.npz") if (work / "surfaces.npz").is_file() else None
    for setting in MONOCONE_SETTINGS:
        if surfaces is not None and _monocone_figure(surfaces, models, layout, setting, out / f"monocone_{setting}.png", shapes):
            lines += ["", f"![{setting}](monocone_{setting}.png)"]
    lines += ["", f"Experiment time {info['seconds'] / 60:.1f} min; per-target scores in `scores.csv`, the table in "
              "Table-1 columns in `monocone.csv`.", "", "## Runs", "", runs_table(cells), ""]
    (out / "monocone.md").write_text("\n".join(lines))
    return out / "monocone.md"


def _monocone_figure(surfaces, models: list[str], layout: Layout, setting: str, path: Path, n: int) -> Path | None:
    """Side views (elevation 0, the cone's axis vertical): ground truth, then each model, first targets."""
    from matplotlib.figure import Figure

    targets = sorted(int(k.split("/")[1]) for k in surfaces.files if k.startswith("gt/"))[:n]
    if not targets:
        return None
    columns = [("ground truth", "gt/{}")] + [(MONOCONE_MODELS.get(m, m), f"{setting}/{m}/{{}}") for m in models]
    fig = Figure(figsize=(2.2 * len(columns), 2.2 * len(targets) + 0.4), layout="constrained")
    axes = fig.subplots(len(targets), len(columns), squeeze=False)
    for col, (title, key) in enumerate(columns):
        for row, target in enumerate(targets):
            points = surfaces[key.format(target)] if key.format(target) in surfaces.files else None
            depth_axis(axes[row, col], points, (-90.0, 0.0))
            if row == 0:
                axes[row, col].set_title(title.replace(" (", "\n("), fontsize=8)
            if col == 0:
                axes[row, col].set_ylabel(f"target {target}", fontsize=8)
    fig.suptitle(f"monocones, {setting} observability (side view, nose up)", fontsize=9)
    fig.savefig(path, dpi=90)
    return path


LAYOUT = Layout("monocone", (*SHAPE_COLUMNS, IOU_S, MATCH_S), write_monocone, ("row", "group"),
                {**{m: f"{t} on monocones" for m, t in MONOCONE_MODELS.items()},
                 **{m + CONTROL: f"{t} on monocones (control: another target's radar)" for m, t in MONOCONE_MODELS.items()}},
                {"full": "full", "partial": "partial (70 % of aspects masked)"})
