"""``rollsym``: the paper's Table 2: ``<model>-<obs>-<noise>`` runs, one table per noise level,
IoU-R / IoU-S / MATCH-S under full and partial observability, with the diagnostics.
"""

from __future__ import annotations

import math
from pathlib import Path

from radar2shape.reporting.cells import Cell, cell_test_config, collect_cells, copy_scores, runs_table
from radar2shape.reporting.figures import run_datamodule
from radar2shape.reporting.layouts.columns import DEPENDENCE_IOU_S, IOU_R, IOU_S, MATCH_S, SHAPES_IOU_S, group_title
from radar2shape.reporting.tables import SEED_SUFFIX, Layout, markdown_table, write_csv


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
    datamodule = run_datamodule(next(iter(chosen.values())).run_dir)
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


LAYOUT = Layout("rollsym", (IOU_R, IOU_S, MATCH_S), write_rollsym, ("row", "group", "section"),
                {"unet": "Profile U-Net diffusion (ours)", "unet_paper": "Profile U-Net diffusion, as in the paper",
                 "unet_cfg": "Profile U-Net diffusion + guidance (drop 0.15, scale 2)",
                 "unet_long": "Profile U-Net diffusion, 200 epochs, step schedule, weight averaging",
                 "unet_500": "Profile U-Net diffusion, 500 epochs, step schedule, weight averaging",
                 "unet_median8": "Profile U-Net diffusion, 200 epochs, median of 8 draws",
                 "unet_mean32": "Profile U-Net diffusion, 200 epochs, mean of 32 draws",
                 "unet_median32": "Profile U-Net diffusion, 200 epochs, median of 32 draws",
                 "unet_500_median32": "Profile U-Net diffusion, 500 epochs, median of 32 draws",
                 "invrt": "InvRT"}, {"full": "Full", "partial": "Partial"},
                noise_title, diagnostics=(DEPENDENCE_IOU_S, SHAPES_IOU_S),
                describe_group=group_title({"full": "Full", "partial": "Partial"}))
