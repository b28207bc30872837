"""Learning curves of a grid's training runs: validation score and training loss against step.

    python scripts/learning_curves.py --grid table1-medium [--metric val/iou_mean] [--out reports/table1-medium] \
        [--runs FOLDER] [--only RUN ...]

Reads ``<out_dir>/<run>/fit/version_0/metrics.csv`` (Lightning's CSV logger) of every fitted run
of the grid (``--runs``: the run folders of an earlier grid state, moved aside, instead of
``out_dir``) and writes ``learning_curves.md`` (one row per validation epoch: step, the metric,
the training loss of that epoch) and ``learning_curves.png``. A run whose log has no value of the
metric (e.g. validation switched off) is listed with what it has. The curves say whether a run
stopped learning or was stopped while learning, which decides between "more steps" and "a
different design".
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from radar2shape.errors import UserInputError  # noqa: E402

SECONDS = "val/fit_seconds"  # logged by the evaluator at each validation


def read_curve(path: Path, metric: str, loss: str = "train/loss_epoch") -> list[dict]:
    """``[{epoch, step, value, loss, seconds}]`` for every epoch that logged ``metric`` (loss: that
    epoch's, or nan; seconds: the fit's wall seconds when that validation began, ``val/fit_seconds``, or nan)."""
    rows = list(csv.DictReader(path.open()))
    losses = {r["epoch"]: float(r[loss]) for r in rows if r.get(loss)}
    seconds = {r["epoch"]: float(r[SECONDS]) for r in rows if r.get(SECONDS)}
    return [{"epoch": int(r["epoch"]), "step": int(r["step"]), "value": float(r[metric]),
             "loss": losses.get(r["epoch"], math.nan), "seconds": seconds.get(r["epoch"], math.nan)}
            for r in rows if r.get(metric)]


def grid_curves(grid_name: str, metric: str, runs: Path | None = None, only: list[str] | None = None) -> dict[str, list[dict]]:
    """Curves of the grid's fitted runs (``only``: of these names) that have a metrics log under
    ``runs`` (default the grid's ``out_dir``), in grid order."""
    from radar2shape.sweep import load_grid

    grid = load_grid(grid_name)
    runs = runs or grid.out_dir
    curves = {}
    unknown = sorted(set(only or ()) - {run.name for run in grid.runs})
    if unknown:
        raise UserInputError(f"--only: {', '.join(unknown)}: not runs of grid {grid.path}")
    for run in grid.runs:
        if run.command != "fit" or (only and run.name not in only):
            continue
        logs = sorted((runs / run.name / "fit").glob("version_*/metrics.csv"), key=lambda p: int(p.parent.name.split("_")[1]))
        if logs:  # a resumed fit logs each sitting in its own version_<k>: one curve, in order
            curves[run.name] = [point for log in logs for point in read_curve(log, metric)]
    return curves


def markdown(curves: dict[str, list[dict]], metric: str) -> str:
    lines = [f"# Learning curves: `{metric}` on the validation subset, by optimiser step", ""]
    for name, curve in curves.items():
        lines += [f"## {name}", ""]
        if not curve:
            lines += [f"no `{metric}` logged", ""]
            continue
        timed = not all(math.isnan(p["seconds"]) for p in curve)  # logs before val/fit_seconds: no column
        header = ["epoch", "step", metric, "train loss (epoch)"] + ["fit seconds"] * timed
        lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += [f"| {p['epoch']} | {p['step']} | {p['value']:.4f} | {p['loss']:.4g} |" + f" {p['seconds']:.0f} |" * timed
                  for p in curve]
        lines.append("")
    return "\n".join(lines)


def figure(curves: dict[str, list[dict]], metric: str, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.5, 4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    for name, curve in curves.items():
        if curve:
            ax.plot([p["step"] for p in curve], [p["value"] for p in curve], marker="o", label=name)
    ax.set(xlabel="optimiser step", ylabel=metric, title="validation learning curves")
    ax.legend(fontsize=7)
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", required=True, help="grid name or file (conf/grid/NAME.yaml)")
    parser.add_argument("--metric", default="val/iou_mean", help="metrics.csv column (default val/iou_mean)")
    parser.add_argument("--out", type=Path, help="output folder (default reports/<grid>)")
    parser.add_argument("--runs", type=Path, help="folder of the run folders (default the grid's out_dir)")
    parser.add_argument("--only", nargs="+", help="these runs of the grid only (default every fitted run)")
    args = parser.parse_args(argv)
    if args.runs is not None and not args.runs.is_dir():
        print(f"error: --runs: {args.runs} is not a folder", file=sys.stderr)
        return 2
    try:
        curves = grid_curves(args.grid, args.metric, args.runs, args.only)
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if not curves:
        print(f"error: no fitted run of grid {args.grid} has a metrics.csv yet", file=sys.stderr)
        return 2
    out = args.out or REPO / "reports" / Path(args.grid).stem
    out.mkdir(parents=True, exist_ok=True)
    (out / "learning_curves.md").write_text(markdown(curves, args.metric))
    figure(curves, args.metric, out / "learning_curves.png")
    print(f"wrote {out / 'learning_curves.md'} and learning_curves.png ({len(curves)} runs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
