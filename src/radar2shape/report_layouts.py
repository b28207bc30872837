"""The report layouts of the project, registered by name in :data:`LAYOUTS`; a grid names one
(``report: table1``) and ``radar2shape report --grid NAME`` writes it.

- ``table1``: the paper's Table 1: rows = models, column groups = test conditions (``<model>-<group>``
  runs), CD / IoU / F-score on the whole test split and on the paper's 20 held-out shapes
  (:func:`paper_subset`), the diagnostics (radar dependence, Stage-1 ceiling, shapes scored), one
  figure per group, the grid's runs and notes;
- ``rollsym``: the paper's Table 2: ``<model>-<obs>-<noise>`` runs, one table per noise level,
  IoU-R / IoU-S / MATCH-S under full and partial observability, with the diagnostics;
- ``demo``: ``make demo``: ``<model>-<obs>`` test runs, one table per observability, and a figure
  of radar, ground truth and each model's reconstruction per test shape;
- ``monocone``: the zero-shot monocone experiment (``scripts/monocone_experiment.py`` leaves
  per-target scores under ``<out_dir>/experiment/``), in Table 1's column layout.

Column groups say what was masked ("partial (70 % of cells masked)", "(70 % per axis)"), read
from each run's saved test config, else from hints in the run name (:func:`masking`).
"""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
from dataclasses import replace

from radar2shape.reporting import (ARCHIVED, SEED_SUFFIX, Cell, Column, Layout, cell_test_config, collect_cells, markdown_table,
                                   pooled, provenance, read_scores, run_notes, runs_table, score_keys, scores_file, write_csv)

CHAMFER = Column("chamfer_l2_x1e3", "CD x10^3 ↓", higher_is_better=False, digits=2)
IOU = Column("iou", "IoU ↑", higher_is_better=True)
FSCORE = Column("fscore_1pct", "F-score@1% ↑", higher_is_better=True)
IOU_R = Column("iou_r", "IoU-R ↑", higher_is_better=True)
IOU_S = Column("iou_s", "IoU-S ↑", higher_is_better=True)
MATCH_S = Column("match_s", "MATCH-S ↓", higher_is_better=False)
SHAPE_COLUMNS = (CHAMFER, IOU, FSCORE)
# Diagnostics (docs/metrics.md): own-radar minus other-radar score, paired over shapes (± standard
# error); the Stage-1 ceiling of latent models; how many shapes each mean pools.
DEPENDENCE_IOU = Column("radar_dependence_iou", "radar dependence Δ IoU ↑", higher_is_better=True, spread="se")
CEILING_IOU = Column("ceiling_iou", "Stage-1 ceiling IoU ↑", higher_is_better=True)
SHAPES_IOU = Column("iou", "shapes scored (IoU)", higher_is_better=True, total="num_shapes")
DEPENDENCE_IOU_S = Column("radar_dependence_iou_s", "radar dependence Δ IoU-S ↑", higher_is_better=True, spread="se")
SHAPES_IOU_S = Column("iou_s", "shapes scored (IoU-S)", higher_is_better=True, total="num_shapes")
SUBSET_SIZE, SUBSET_SEED = 20, 0  # the paper's "20 random held-out meshes"

MODEL_TITLES = {
    "radar2shape": "Radar2Shape",
    "radar2shape_paper": "Radar2Shape, as in the paper",
    "radar2shape_s1slow": "Radar2Shape, slow-decay Stage 1",
    "radar2shape_s1wide": "Radar2Shape, wide Stage 1",
    "diffusion_sdf": "Diffusion-SDF",
    "tmnet": "TMNet",
    "list": "LIST",
    "nearest": "Nearest neighbour",
    "mean_shape": "Mean shape",
    "radar2shape_lora": "Radar2Shape + LoRA (PO-SBR fine-tuned)",
}
GROUP_TITLES = {
    "full": "full",
    "partial": "partial",
    "full-sbr": "PO-SBR test, full",
    "partial-sbr": "PO-SBR test, partial",
}


# ---- what a run masked ------------------------------------------------------------------------
def masking(cell: Cell, group: str) -> str | None:
    """What the run's test mask hid, e.g. "70 % of cells masked", "70 % per axis"; None when full.

    From the saved test config (``observability``, ``mask_rule``: ``cells`` or ``per_axis``,
    ``test_keep``: the kept fraction); without one, from the run's group name (``cells`` / ``axis``
    and a percentage, e.g. ``partial70cells``); "mask not recorded" when neither says.
    """
    config = cell_test_config(cell)
    if config is not None and "observability" in config:
        if config["observability"] != "partial":
            return None
        masked = round(100 * (1 - float(config.get("test_keep", 0.3))))
        if "Profile" in config["class_path"]:  # one angular axis: both rules mask that share of aspects
            return f"{masked} % of aspects masked"
        rule = config.get("mask_rule", "per_axis")
        return f"{masked} % of cells masked" if rule == "cells" else f"{masked} % per axis"
    if "partial" not in group:
        return None
    percent = re.search(r"(\d+)", group)
    amount = f"{percent.group(1)} % " if percent else ""
    if "cell" in group:
        return f"{amount}of cells masked"
    if "axis" in group:
        return f"{amount}per axis"
    return "mask not recorded"


def group_title(titles: dict[str, str]):
    """A ``describe_group`` for a layout: the static title plus what the group's runs masked."""

    def describe(group: str, cells: list[Cell]) -> str:
        base = titles.get(group, group)
        found = {masking(cell, group) for cell in cells if cell.state in ("done", "tested", ARCHIVED)} - {None}  # runs not done say nothing
        if not found:
            return base
        return f"{base} ({found.pop()})" if len(found) == 1 else f"{base} (masks differ: {', '.join(sorted(found))})"

    return describe


# ---- per-shape scores: counts and the paper's 20-shape subset -------------------------------------
def per_shape_scores(cell: Cell) -> list[dict] | None:
    """Rows of the per-shape test scores behind a cell (None if it has none)."""
    path = scores_file(cell)
    return read_scores(path) if path is not None else None


def paper_subset(n_records: int, size: int = SUBSET_SIZE, seed: int = SUBSET_SEED) -> list[int]:
    """Record indices of the fixed held-out subset: ``default_rng(seed).choice(n_records, size)``, sorted.

    The same for every model scored on the same split (all of it when it has at most ``size`` shapes).
    """
    if n_records <= size:
        return list(range(n_records))
    return sorted(int(i) for i in np.random.default_rng(seed).choice(n_records, size, replace=False))


def subset_cells(cells: list[Cell]) -> tuple[list[Cell], int | None]:
    """The cells re-pooled over :func:`paper_subset` of their per-shape scores, and the split size it was drawn from."""
    out, sizes = [], set()
    for cell in cells:
        rows = per_shape_scores(cell)
        if not rows:
            out.append(Cell(cell.name, cell.run_dir, cell.state))
            continue
        n_records = int(cell.metrics.get("num_shapes", len(rows)))
        sizes.add(n_records)
        chosen = set(paper_subset(n_records))
        out.append(Cell(cell.name, cell.run_dir, cell.state, cell.record,
                        pooled([r for r in rows if int(r["index"]) in chosen], score_keys(rows))))
    return out, (sizes.pop() if len(sizes) == 1 else None)


def copy_scores(cells: list[Cell], folder: Path) -> int:
    """Each finished or archived run's per-shape test scores as ``folder/<run>.csv``, with its
    :func:`provenance` as ``folder/<run>.json``; returns how many."""
    copied = 0
    for cell in cells:
        path = scores_file(cell)
        if path is not None:
            folder.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, folder / f"{cell.name}.csv")
            (folder / f"{cell.name}.json").write_text(json.dumps(provenance(cell), indent=1, sort_keys=True))
            copied += 1
    return copied


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


def one_replicate_per_row(cells: list[Cell], layout: Layout, n_saved: dict[str, int]) -> list[Cell]:
    """One cell per table row: of a row's seed replicates (``-seed<k>``), the one that saved the most
    test reconstructions (the first on a tie), so that a figure shows each model once."""
    best: dict[str, Cell] = {}
    for c in cells:
        row = layout.split(c.name)["row"]
        if row not in best or n_saved[c.name] > n_saved[best[row].name]:
            best[row] = c
    return list(best.values())


def model_rows_figure(cells: list[Cell], layout: Layout, path: Path, n_shapes: int, title: str) -> Path | None:
    """Ground truth, then one row per model, for the first ``n_shapes`` test shapes the runs saved
    (seed replicates: see :func:`one_replicate_per_row`)."""
    from matplotlib.figure import Figure

    from radar2shape.metrics.render import VIEWS

    saved = {c.name: saved_reconstructions(c.run_dir) for c in cells}
    cells = one_replicate_per_row(cells, layout, {name: len(found) for name, found in saved.items()})
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
def stage1_rows(cells: list[Cell], layout: Layout) -> list[tuple[str, dict]]:
    """``(run name, test metrics)`` of the finished auxiliary runs (no row/group in their name) that scored IoU."""
    return [(cell.name, cell.metrics) for cell in cells
            if layout.split(cell.name) is None and cell.state in ("done", ARCHIVED) and "iou_mean" in cell.metrics]


def write_table1(grid, out: Path, layout: Layout, shapes: int, archive: Path | None = None) -> Path:
    """``NAME.md`` / ``NAME.csv`` (one table, groups side by side), ``NAME_20shapes.csv`` (the paper's
    held-out subset), ``NAME_diagnostics.csv``, ``scores/<run>.csv`` (per-shape) and ``NAME_<group>.png``."""
    name = grid.name
    cells, outside = collect_cells(grid, archive)
    tables = layout.tables(cells)
    _, rows, columns = tables[0] if tables else (None, [], [])
    write_csv(rows, columns, out / f"{name}.csv")
    subset, n_records = subset_cells(cells)
    _, subset_rows, subset_columns = (layout.tables(subset) or [(None, [], [])])[0]
    write_csv(subset_rows, subset_columns, out / f"{name}_20shapes.csv")
    _, diag_rows, diag_columns = (layout.tables(cells, layout.diagnostics) or [(None, [], [])])[0]
    write_csv(diag_rows, diag_columns, out / f"{name}_diagnostics.csv")
    copied = copy_scores(cells, out / "scores")
    groups = list(dict.fromkeys(w["group"] for c in cells if (w := layout.split(c.name))))
    figures = []
    for group in groups:
        in_group = [c for c in cells if (layout.split(c.name) or {}).get("group") == group]
        kept = archive.parent / f"{name}_{group}.png" if archive is not None else None
        if kept is not None and kept.is_file() and any(c.state == ARCHIVED for c in in_group):
            figure = kept  # rows of archived runs cannot be redrawn: the last drawing stands, not one without them
        else:
            figure = model_rows_figure([c for c in in_group if c.state == "done"], layout, out / f"{name}_{group}.png",
                                       shapes, layout.group_title(group, in_group))
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
        sampling_line(cells),
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
    stages = stage1_rows(cells, layout)
    if stages:
        text += [
            "### First stages on the test split",
            "",
            "Auxiliary runs (names without `-`): each first stage autoencodes the test shapes from their "
            "surface points and decodes the posterior means, the same quantity as the Stage-1 ceiling below.",
            "",
            markdown_table(stages, list(SHAPE_COLUMNS + (SHAPES_IOU,))),
            "",
        ]
    text += [
        f"### On the paper's {SUBSET_SIZE} held-out shapes",
        "",
        f"The same runs re-pooled over a fixed subset of the test split: record indices "
        f"`numpy.random.default_rng({SUBSET_SEED}).choice(N, {SUBSET_SIZE}, replace=False)`"
        + (f" with N = {n_records}" if n_records else "") + " (the whole split when N <= "
        f"{SUBSET_SIZE}), from each run's per-shape scores (`scores/<run>.csv`, {copied} runs).",
        "",
        markdown_table(subset_rows, subset_columns),
        "",
        "### Diagnostics",
        "",
        "Radar dependence: IoU from the shape's own radar minus IoU from another test shape's radar (a fixed "
        "derangement: the shape before it in the test split), mean ± standard error of the paired differences; "
        "near zero means the model is a shape prior, whatever its IoU. Stage-1 ceiling: IoU of the first stage's "
        "posterior means decoded (latent models only), a bound on what the second stage can reach. Shapes scored: "
        "shapes with a defined IoU, of those evaluated.",
        "",
        markdown_table(diag_rows, diag_columns),
        "",
    ]
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


def noise_level(cells: list[Cell], section: str) -> str:
    """A section's title from its runs' saved test configs ("Low noise (-60 dB re peak)"), else
    :func:`noise_title` of its name; "levels differ" when the runs disagree."""
    found = set()
    for cell in cells:
        parts = SEED_SUFFIX.sub("", cell.name).split("-")
        config = cell_test_config(cell) if len(parts) == 3 and parts[2] == section else None
        if config is not None and "test_noise_db" in config:
            reference = " re peak" if config.get("noise_reference") == "peak" else " dBsm" if config.get("noise_reference") == "absolute" else ""
            found.add(f"{float(config['test_noise_db']):g} dB{reference}".replace("dB dBsm", "dBsm"))
    if len(found) == 1:
        return f"{section.capitalize()} noise ({found.pop()})"
    return noise_title(section) if not found else f"{section.capitalize()} noise (levels differ: {', '.join(sorted(found))})"


PROFILE_FIGURE_SHAPES = 8


def profile_figure(cells: list[Cell], layout: Layout, path: Path, n_shapes: int = PROFILE_FIGURE_SHAPES) -> Path | None:
    """Predicted against true profiles of the first ``n_shapes`` test shapes, one panel per shape.

    For each setting (``<obs>-<noise>``) of the first seed of every model that finished it, the
    checkpoint predicts the test batch of its own saved test config (same masks and noise as its
    scores); one figure per observability at the lowest noise level the grid has.
    """
    import torch
    from matplotlib.figure import Figure

    from radar2shape.commands.reconstruct import load_model

    chosen: dict[str, Cell] = {}
    for cell in cells:
        where = layout.split(cell.name)
        if cell.state == "done" and where and "checkpoint" in cell.record and where["row"] not in chosen \
                and where["group"] == "full" and where["section"] == _first_section(cells, layout):
            chosen[where["row"]] = cell
    if not chosen:
        return None
    datamodule = _test_data(next(iter(chosen.values())).run_dir)
    if datamodule is None:
        return None
    batch = next(iter(datamodule.test_dataloader()))
    batch = {k: v[:n_shapes] for k, v in batch.items()}
    truth = batch["profile"].numpy()
    predictions = {}
    torch.manual_seed(0)
    for row, cell in chosen.items():
        model = load_model(cell.run_dir / cell.record["checkpoint"])
        predictions[layout.row_title(row)] = model.predict_profiles(batch)
    columns = 4
    fig = Figure(figsize=(2.4 * columns, 2.6 * math.ceil(len(truth) / columns)))
    axes = fig.subplots(math.ceil(len(truth) / columns), columns, squeeze=False).ravel()
    for i, ax in enumerate(axes):
        if i >= len(truth):
            ax.axis("off")
            continue
        ax.plot(truth[i][:, 0], truth[i][:, 1], "k-", lw=2.0, label="ground truth")
        for title, profiles in predictions.items():
            ax.plot(profiles[i][:, 0], profiles[i][:, 1], "-", lw=1.2, label=title)
        ax.set_xlim(0, 0.55)
        ax.set_ylim(-0.55, 0.55)
        ax.set_aspect("equal")
        ax.set_title(f"test #{int(batch['index'][i])}", fontsize=8)
        ax.tick_params(labelsize=6)
    axes[0].legend(fontsize=6, loc="upper right")
    section = _first_section(cells, layout)
    level = noise_level(cells, section)
    fig.suptitle(f"profiles (r, z), full observability, {level[0].lower() + level[1:]}: "
                 "truth and each model's prediction", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path


def _first_section(cells: list[Cell], layout: Layout) -> str | None:
    """The first noise level in run order (the grid lists the lowest first)."""
    for cell in cells:
        where = layout.split(cell.name)
        if where:
            return where["section"]
    return None


def noise_degradation(tables, cells: list[Cell], metric: str = "iou_s") -> str | None:
    """Markdown: each model's ``metric`` mean at every noise level and first level minus last, per
    observability (what the noise axis costs each model); None with fewer than two levels."""
    levels = [section for section, _, _ in tables]
    if len(levels) < 2:
        return None
    values: dict[str, dict[str, dict[str, float]]] = {}  # model -> group -> level -> mean
    groups: list[str] = []
    for section, rows, _ in tables:
        for title, metrics in rows:
            for key, value in metrics.items():
                group, _, name = key.rpartition("/")
                if "/" not in group and name == f"{metric}_mean" and not math.isnan(value):  # not per class
                    values.setdefault(title, {}).setdefault(group, {})[section] = value
                    groups += [group] if group not in groups else []
    header = ["model"] + [f"{g.capitalize()}: {noise_level(cells, lv).split(' (')[0].lower()}" for g in groups for lv in levels]
    header += [f"{g.capitalize()}: {levels[0]} − {levels[-1]}" for g in groups]
    lines = ["| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
    for title, by_group in values.items():
        cells_row = [f"{by_group.get(g, {}).get(lv, math.nan):.3f}" for g in groups for lv in levels]
        for g in groups:
            first, last = by_group.get(g, {}).get(levels[0], math.nan), by_group.get(g, {}).get(levels[-1], math.nan)
            cells_row.append(f"{first - last:+.3f}")
        lines.append(f"| {title} | " + " | ".join("n/a" if "nan" in c else c for c in cells_row) + " |")
    return "\n".join(lines)


def write_rollsym(grid, out: Path, layout: Layout, shapes: int, archive: Path | None = None) -> Path:
    """``table.md`` / ``table.csv`` / ``diagnostics.csv``: one table and one diagnostics table per noise
    level (CSV rows ``<noise>/<model>``), and the per-shape scores ``scores/<run>.csv``."""
    cells, _ = collect_cells(grid, archive)
    tables = layout.tables(cells)
    diagnostics = layout.tables(cells, layout.diagnostics)
    sections = [f"### {noise_level(cells, s)}\n\n{markdown_table(rows, columns)}\n\n"
                f"Diagnostics:\n\n{markdown_table(diag_rows, diag_columns)}"
                for (s, rows, columns), (_, diag_rows, diag_columns) in zip(tables, diagnostics)]
    copied = copy_scores(cells, out / "scores")
    figure = profile_figure(cells, layout, out / "profiles.png")
    degradation = noise_degradation(tables, cells)
    if degradation:
        sections.append("### What noise costs (IoU-S, mean over seeds)\n\n" + degradation)
    text = "\n\n".join(
        [f"## Roll-symmetric reconstruction ({grid.path.name})",
         "Test-set mean ± std. IoU-R: radar IoU at 20 dB below peak; IoU-S: half-section IoU; "
         "MATCH-S: mean matched-point distance (unit-cube units). Definitions: docs/rollsym.md. "
         "Diagnostics: radar dependence = IoU-S from the shape's own radar minus IoU-S from another test "
         "shape's radar (a fixed derangement), mean ± standard error of the paired differences; shapes scored = "
         f"shapes with a defined IoU-S, of those evaluated. Per-shape scores: `scores/<run>.csv` ({copied} runs).",
         *sections, "### Runs", runs_table(cells),
         *([f"![profiles]({figure.name})"] if figure else [])]
    ) + "\n"
    (out / "table.md").write_text(text)
    if tables:
        csv_rows = [(f"{section}/{title}", metrics) for section, rows, _ in tables for title, metrics in rows]
        write_csv(csv_rows, tables[0][2], out / "table.csv")
        diag_csv = [(f"{section}/{title}", metrics) for section, rows, _ in diagnostics for title, metrics in rows]
        write_csv(diag_csv, diagnostics[0][2], out / "diagnostics.csv")
    return out / "table.md"


# ---- demo ----------------------------------------------------------------------------------------
def write_demo(grid, out: Path, layout: Layout, shapes: int, archive: Path | None = None) -> Path:
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
        Layout("table1", SHAPE_COLUMNS, write_table1, ("row", "group"), MODEL_TITLES, GROUP_TITLES,
               diagnostics=(DEPENDENCE_IOU, CEILING_IOU, SHAPES_IOU), describe_group=group_title(GROUP_TITLES)),
        Layout("rollsym", (IOU_R, IOU_S, MATCH_S), write_rollsym, ("row", "group", "section"),
               {"unet": "Profile U-Net diffusion (ours)", "unet_paper": "Profile U-Net diffusion, as in the paper",
                "unet_cfg": "Profile U-Net diffusion + guidance (drop 0.15, scale 2)",
                "invrt": "InvRT"}, {"full": "Full", "partial": "Partial"},
               noise_title, diagnostics=(DEPENDENCE_IOU_S, SHAPES_IOU_S),
               describe_group=group_title({"full": "Full", "partial": "Partial"})),
        Layout("demo", SHAPE_COLUMNS, write_demo, ("row", "section"),
               {"radar2shape": "Radar2Shape", "nearest": "nearest-neighbour", "mean_shape": "mean-shape"}, {},
               lambda obs: f"{obs.capitalize()} observability"),
        Layout("monocone", (*SHAPE_COLUMNS, IOU_S, MATCH_S), write_monocone, ("row", "group"),
               {**{m: f"{t} on monocones" for m, t in MONOCONE_MODELS.items()},
                **{m + CONTROL: f"{t} on monocones (control: another target's radar)" for m, t in MONOCONE_MODELS.items()}},
               {"full": "full", "partial": "partial (70 % of aspects masked)"}),
    ]
}
