"""The report layouts of the project, registered by name in :data:`LAYOUTS`; a grid names one
(``report: table1``) and ``radar2shape report --grid NAME`` writes it.

- ``table1``: the paper's Table 1: rows = models, column groups = test conditions (``<model>-<group>``
  runs), CD / IoU / F-score, one figure per group, the grid's runs and notes;
- ``rollsym``: the paper's Table 2: ``<model>-<obs>-<noise>`` runs, one table per noise level,
  IoU-R / IoU-S / MATCH-S under full and partial observability;
- ``demo``: ``make demo``: ``<model>-<obs>`` test runs, one table per observability, and a figure
  of radar, ground truth and each model's reconstruction per test shape;
- ``monocone``: the zero-shot monocone experiment (``scripts/monocone_experiment.py`` leaves
  per-target scores under ``<out_dir>/experiment/``), in Table 1's column layout.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np

from radar2shape.reporting import Cell, Column, Layout, collect_cells, markdown_table, run_notes, runs_table, write_csv

CHAMFER = Column("chamfer_l2_x1e3", "CD x10^3 ↓", higher_is_better=False, digits=2)
IOU = Column("iou", "IoU ↑", higher_is_better=True)
FSCORE = Column("fscore_1pct", "F-score@1% ↑", higher_is_better=True)
IOU_R = Column("iou_r", "IoU-R ↑", higher_is_better=True)
IOU_S = Column("iou_s", "IoU-S ↑", higher_is_better=True)
MATCH_S = Column("match_s", "MATCH-S ↓", higher_is_better=False)
SHAPE_COLUMNS = (CHAMFER, IOU, FSCORE)

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
VIEW = (-55.0, 25.0)  # azimuth, elevation in degrees: front three-quarter


# ---- figures -------------------------------------------------------------------------------------
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


def _test_data(run_dir: Path):
    """The DataModule of a run's saved test config, set up for ``test`` (None without a config)."""
    import importlib

    import yaml

    configs = sorted(run_dir.glob("test/**/config.yaml"))
    if not configs:
        return None
    spec = yaml.safe_load(configs[-1].read_text()).get("data") or {}
    module, _, cls = str(spec.get("class_path", "")).rpartition(".")
    if not module:
        return None
    datamodule = getattr(importlib.import_module(module), cls)(**(spec.get("init_args") or {}))
    datamodule.setup("test")
    return datamodule


def ground_truth(run_dir: Path, indices: list[int]) -> dict[int, np.ndarray]:
    """``eval_points`` of test records by index, from the DataModule of the run's saved test config."""
    datamodule = _test_data(run_dir)
    if datamodule is None:
        return {}
    wanted, found = set(indices), {}
    for batch in datamodule.test_dataloader():
        for i, points in zip(batch["index"].tolist(), batch["eval_points"].numpy()):
            if i in wanted:
                found[i] = points
        if len(found) == len(wanted):
            break
    return found


def _depth_axis(ax, points: np.ndarray | None, view=VIEW) -> None:
    from radar2shape.metrics.render import depth_image

    if points is None or len(points) == 0:
        ax.text(0.5, 0.5, "not saved", ha="center", va="center")
    else:
        ax.imshow(depth_image(points, *view), cmap="viridis", vmin=-0.6, vmax=0.6)
    ax.set_xticks([])
    ax.set_yticks([])


def model_rows_figure(cells: list[Cell], layout: Layout, path: Path, n_shapes: int, title: str) -> Path | None:
    """Ground truth, then one row per model, for the first ``n_shapes`` test shapes the runs saved."""
    from matplotlib.figure import Figure

    from radar2shape.metrics.render import VIEWS

    saved = {c.name: saved_reconstructions(c.run_dir) for c in cells}
    indices = sorted(set().union(*saved.values()))[:n_shapes] if saved else []
    if not indices:
        return None
    rows = [("ground truth", ground_truth(cells[0].run_dir, indices))]
    rows += [(layout.row_title(layout.split(c.name)["row"]), {i: load_points(p) for i, p in saved[c.name].items()}) for c in cells]
    fig = Figure(figsize=(2.0 * len(indices) + 1.2, 2.0 * len(rows)))
    axes = fig.subplots(len(rows), len(indices), squeeze=False)
    for r, (label, points) in enumerate(rows):
        for c, index in enumerate(indices):
            _depth_axis(axes[r, c], points.get(index, np.zeros((0, 3))), VIEWS[0])
            if r == 0:
                axes[r, c].set_title(f"test #{index}", fontsize=9)
            if c == 0:
                axes[r, c].set_ylabel(label, fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path


def radar_shapes_figure(cells: list[Cell], layout: Layout, path: Path, n_shapes: int) -> Path | None:
    """Rows: test shapes; columns: radar dB image (mid frequency), ground truth, then one per model."""
    from matplotlib.figure import Figure

    from radar2shape.radar import to_db

    datamodule = _test_data(cells[0].run_dir) if cells else None
    if datamodule is None:
        return None
    records = datamodule.records("test")
    count = min(n_shapes, len(records))
    saved = [saved_reconstructions(c.run_dir) for c in cells]
    columns = ["radar (dB, mid band)", "ground truth", *(layout.row_title(layout.split(c.name)["row"]) for c in cells)]
    fig = Figure(figsize=(2.3 * len(columns), 2.3 * count))
    axes = fig.subplots(count, len(columns), squeeze=False)
    for row in range(count):
        record = records[row]
        radar_db = to_db(record["radar"])
        axes[row, 0].imshow(radar_db[:, :, radar_db.shape[2] // 2], cmap="magma", aspect="auto")
        axes[row, 0].set_xticks([])
        axes[row, 0].set_yticks([])
        clouds = [record["eval_points"]] + [load_points(s[row], 20000) if row in s else None for s in saved]
        for col, points in enumerate(clouds, start=1):
            _depth_axis(axes[row, col], points)
        axes[row, 0].set_ylabel(str(record.get("class_name", f"test #{row}")), fontsize=9)
    for col, title in enumerate(columns):
        axes[0, col].set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path


# ---- table1 --------------------------------------------------------------------------------------
def write_table1(grid, out: Path, layout: Layout, shapes: int) -> Path:
    """``NAME.md`` / ``NAME.csv`` (one table, groups side by side) and ``NAME_<group>.png``."""
    name = grid.name
    cells, outside = collect_cells(grid)
    tables = layout.tables(cells)
    _, rows, columns = tables[0] if tables else (None, [], [])
    write_csv(rows, columns, out / f"{name}.csv")
    groups = list(dict.fromkeys(w["group"] for c in cells if (w := layout.split(c.name))))
    figures = []
    for group in groups:
        done = [c for c in cells if c.state == "done" and (layout.split(c.name) or {}).get("group") == group]
        figure = model_rows_figure(done, layout, out / f"{name}_{group}.png", shapes, GROUP_TITLES.get(group, group))
        figures += [figure] if figure else []
    text = [
        f"# {name}: reconstruction from radar",
        "",
        f"Grid `{grid.path}`, runs in `{grid.out_dir}`. Cells: mean ± std over the test set; Chamfer-L2 x10^3 "
        "(lower is better), volumetric IoU and F-score at 1 % of the unit cube (higher is better); "
        "best of each column in bold. `n/a`: run missing, failed, or the metric is undefined (IoU of point sets).",
        "",
        markdown_table(rows, columns),
        "",
    ]
    if outside:  # not the grid's test protocol, so never in its table, its bold or its CSV
        (_, extra_rows, extra_columns), *_ = layout.tables(outside)
        text += [
            "Rows tested outside the grid (folders of the run directory that the grid does not list, e.g. "
            "written by another experiment; their test data and protocol are their own, so they "
            "are not compared with the table above):",
            "",
            markdown_table(extra_rows, extra_columns),
            "",
        ]
    notes = run_notes(cells + outside)
    text += ["Notes on individual runs:", "", *notes, ""] if notes else []
    text += ["## Runs", "", runs_table(cells + outside), ""]
    text += [f"![{f.stem}]({f.name})\n" for f in figures]
    path = out / f"{name}.md"
    path.write_text("\n".join(text))
    return path


# ---- rollsym (Table 2) -----------------------------------------------------------------------------
NOISE_DB = {"low": -80, "medium": -60, "high": -40}


def noise_title(noise: str) -> str:
    level = NOISE_DB.get(noise)
    return f"{noise.capitalize()} noise ({level} dB)" if level is not None else noise


def write_rollsym(grid, out: Path, layout: Layout, shapes: int) -> Path:
    """``table.md`` / ``table.csv``: one table per noise level (CSV rows ``<noise>/<model>``)."""
    cells, _ = collect_cells(grid)
    tables = layout.tables(cells)
    sections = [f"### {layout.section_title(s)}\n\n{markdown_table(rows, columns)}" for s, rows, columns in tables]
    text = "\n\n".join(
        [f"## Roll-symmetric reconstruction ({grid.path.name})",
         "Test-set mean ± std. IoU-R: radar IoU at 20 dB below peak; IoU-S: half-section IoU; "
         "MATCH-S: mean matched-point distance (unit-cube units). Definitions: docs/rollsym.md.",
         *sections, "### Runs", runs_table(cells)]
    ) + "\n"
    (out / "table.md").write_text(text)
    if tables:
        csv_rows = [(f"{section}/{title}", metrics) for section, rows, _ in tables for title, metrics in rows]
        write_csv(csv_rows, tables[0][2], out / "table.csv")
    return out / "table.md"


# ---- demo ----------------------------------------------------------------------------------------
def write_demo(grid, out: Path, layout: Layout, shapes: int) -> Path:
    """``README.md``, ``table_<obs>.csv`` and ``reconstructions.png`` (full observability)."""
    cells, _ = collect_cells(grid)
    lines = ["# radar2shape demo", "",
             "Tiny procedural `parts` dataset (conf/data/parts_tiny.yaml), CPU-sized Stage 1 (SDF-VAE) and Stage 2 (radar diffusion).",
             "Metrics on the test split, mean ± std over shapes (DESIGN.md section 6: Chamfer-L2 x10^3 on",
             "2,048 points here for speed, volumetric IoU, F-score at 1 % of the unit cube). Best per column in bold.", ""]
    results = {}
    for section, rows, columns in layout.tables(cells):
        lines += [f"## {layout.section_title(section)}", "", markdown_table(rows, columns), ""]
        write_csv(rows, columns, out / f"table_{section}.csv")
        results[section] = dict(rows)
    full = results.get("full", {})
    ours, mean_shape = layout.row_title("radar2shape"), layout.row_title("mean_shape")
    if ours in full and mean_shape in full:
        beats = all(full[ours].get(f"{k}_mean", 0) > full[mean_shape].get(f"{k}_mean", 0) for k in ("iou", "fscore_1pct"))
        lines += [f"Radar2Shape beats the mean-shape guess on IoU and F-score (full observability): "
                  f"**{'yes' if beats else 'no'}**.", ""]
    shown = [c for c in cells if c.state == "done" and (layout.split(c.name) or {}).get("section") == "full"]
    if radar_shapes_figure(shown, layout, out / "reconstructions.png", shapes):
        lines += ["## Reconstructions (full observability)", "", "![reconstructions](reconstructions.png)", ""]
    lines += ["## Runs", "", runs_table(cells), ""]
    (out / "README.md").write_text("\n".join(lines))
    return out / "README.md"


# ---- monocone ------------------------------------------------------------------------------------
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
            metrics[f"{column.key}_mean"], metrics[f"{column.key}_std"] = _mean_std([float(r[column.key]) for r in rows])
        out.append(Cell(name, Path(), "done", {}, metrics))
    return out


def write_monocone(grid, out: Path, layout: Layout, shapes: int) -> Path:
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
    (_, rows, columns), *_ = layout.tables(monocone_cells(scores, layout.columns))
    write_csv(rows, columns, out / "monocone.csv")
    low, high = info["model_band_ghz"]
    size = info["size_m"]
    lines += [f"{info['targets']} blunted cones (`{info['data_config']}`), measured in simulation at {size:g} m length: PO, "
              f"aspect-only (roll 0), aspects 0-180 deg every {info['aspect_step_deg']:g} deg, {info['num_freq']} "
              f"frequencies over {low / size:g}-{high / size:g} GHz (= {low:g}-{high:g} GHz at the models' 1 m), "
              f"complex noise at {info['noise_db']:g} dBsm (1 m scale), written as generic CSV and read back through "
              f"`radar.measured` with `--size-m {size:g}`. Partial: one contiguous aspect window keeping "
              f"{100 * info['keep']:.0f} % of the aspects, the other rows absent (masked on the model grid). "
              "No model saw a monocone in training (zero-shot): the 3D model was trained on `parts_tiny`, the "
              "profile models on `frusta_rollsym`.", "",
              "Cells: mean ± std over the targets, best of each column in bold. CD = Chamfer-L2 x10^3, IoU volumetric, "
              "F-score at 1 % of the unit cube; IoU-S / MATCH-S compare the half cross-sections (docs/rollsym.md; a 3D "
              "mesh that is not a solid of revolution scores IoU-S 0 and no MATCH-S). Control rows: each target "
              "reconstructed from the next target's radar.", "",
              markdown_table(rows, columns), "",
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
            _depth_axis(axes[row, col], points, (-90.0, 0.0))
            if row == 0:
                axes[row, col].set_title(title.replace(" (", "\n("), fontsize=8)
            if col == 0:
                axes[row, col].set_ylabel(f"target {target}", fontsize=8)
    fig.suptitle(f"monocones, {setting} observability (side view, nose up)", fontsize=9)
    fig.savefig(path, dpi=90)
    return path


# ---- the registry ----------------------------------------------------------------------------------
LAYOUTS: dict[str, Layout] = {
    layout.name: layout
    for layout in [
        Layout("table1", SHAPE_COLUMNS, write_table1, ("row", "group"), MODEL_TITLES, GROUP_TITLES),
        Layout("rollsym", (IOU_R, IOU_S, MATCH_S), write_rollsym, ("row", "group", "section"),
               {"unet": "Profile U-Net diffusion (ours)", "invrt": "InvRT"}, {"full": "Full", "partial": "Partial"},
               noise_title),
        Layout("demo", SHAPE_COLUMNS, write_demo, ("row", "section"),
               {"radar2shape": "Radar2Shape", "nearest": "nearest-neighbour", "mean_shape": "mean-shape"}, {},
               lambda obs: f"{obs.capitalize()} observability"),
        Layout("monocone", (*SHAPE_COLUMNS, IOU_S, MATCH_S), write_monocone, ("row", "group"),
               {**{m: f"{t} on monocones" for m, t in MONOCONE_MODELS.items()},
                **{m + CONTROL: f"{t} on monocones (control: another target's radar)" for m, t in MONOCONE_MODELS.items()}},
               {"full": "full", "partial": "partial (70 % of aspects masked)"}),
    ]
}
