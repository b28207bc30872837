"""``table1``: the paper's Table 1: rows = models, column groups = test conditions (``<model>-<group>``
runs), CD / IoU / F-score on the whole test split and on the paper's 20 held-out shapes
(:func:`paper_subset`), the diagnostics (radar dependence, Stage-1 ceiling, shapes scored), one
figure per group, the grid's runs and notes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from radar2shape.reporting.cells import (ARCHIVED, Cell, collect_cells, copy_scores, pooled, read_scores, run_notes,
                                         runs_table, sampling_line, score_keys, scores_file)
from radar2shape.reporting.figures import model_rows_figure
from radar2shape.reporting.layouts.columns import (CEILING_IOU, DEPENDENCE_IOU, GROUP_TITLES, MODEL_TITLES,
                                                   SHAPE_COLUMNS, SHAPES_IOU, group_title)
from radar2shape.reporting.tables import Layout, markdown_table, write_csv


SUBSET_SIZE, SUBSET_SEED = 20, 0  # the paper's "20 random held-out meshes"


# ---- per-shape scores: the paper's 20-shape subset ------------------------------------------------
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


LAYOUT = Layout("table1", SHAPE_COLUMNS, write_table1, ("row", "group"), MODEL_TITLES, GROUP_TITLES,
                diagnostics=(DEPENDENCE_IOU, CEILING_IOU, SHAPES_IOU), describe_group=group_title(GROUP_TITLES))
