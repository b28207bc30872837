"""Reconstruction figure of chosen runs of a grid: ground truth, then one row per run, same test shapes.

    python scripts/reconstruction_figure.py --grid table1-medium \
        --runs radar2shape_s1slow-full list-full diffusion_sdf-full-seed0 nearest-full \
        --out reports/table1-medium/baselines/reconstructions_full.png [--shapes 6]

The report draws one figure per column group from every finished run of the group, and keeps its
last drawing while any run of the group is archived (its folder on another machine: its meshes
cannot be redrawn). This draws a figure from the runs on this machine that the caller names, in
the caller's order, with the report's drawing (``reporting.figures.model_rows_figure``) and row titles.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from radar2shape.errors import UserInputError  # noqa: E402


def draw(grid_name: str, runs: list[str], out: Path, shapes: int) -> list[str]:
    """Draw the figure; returns its row titles (ground truth first)."""
    from radar2shape.reporting import collect_cells, get_layout, model_rows_figure, saved_reconstructions
    from radar2shape.sweep import load_grid

    grid = load_grid(grid_name)
    layout = get_layout(grid.report or "table1")
    cells = {cell.name: cell for cell in collect_cells(grid)[0]}
    for name in runs:
        if name not in cells:
            raise UserInputError(f"--runs: {name!r} is not a run of grid {grid.path}")
        if cells[name].state != "done" or not saved_reconstructions(cells[name].run_dir):
            raise UserInputError(f"--runs: {name} has no saved test reconstructions in {cells[name].run_dir} "
                                 f"(state {cells[name].state})")
    chosen = [cells[name] for name in runs]
    rows = [layout.split(name)["row"] for name in runs]
    if len(set(rows)) != len(rows):
        raise UserInputError(f"--runs: one run per table row (seed replicates of one row: pick one), got rows {rows}")
    out.parent.mkdir(parents=True, exist_ok=True)
    title = f"{grid.name}: " + ", ".join(runs)
    if model_rows_figure(chosen, layout, out, shapes, title) is None:
        raise UserInputError("--runs: the runs saved no test shapes to draw")
    return ["ground truth"] + [layout.row_title(row) for row in rows]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", required=True, help="grid name or file (conf/grid/NAME.yaml)")
    parser.add_argument("--runs", nargs="+", required=True, help="finished runs of the grid, one per row, in order")
    parser.add_argument("--out", type=Path, required=True, help="output PNG")
    parser.add_argument("--shapes", type=int, default=6, help="test shapes (columns), the first ones saved (default 6)")
    args = parser.parse_args(argv)
    if args.shapes < 1:
        print(f"error: --shapes: expected a positive count, got {args.shapes}", file=sys.stderr)
        return 2
    try:
        titles = draw(args.grid, args.runs, args.out, args.shapes)
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: rows {', '.join(titles)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
