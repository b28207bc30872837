"""The roll-symmetric results in the layout of the paper's Table 2, from a finished sweep.

    python scripts/rollsym_table.py --grid conf/grid/rollsym.yaml [--out reports/rollsym]

Reads ``<out_dir>/<model>-<obs>-<noise>/metrics.json`` and ``done`` of every run of the grid
(names from its ``matrix``: axes model, obs, noise) and writes ``table.md`` and ``table.csv``:
one table per noise level, a row per model, IoU-R / IoU-S / MATCH-S (mean ± std over the test
set) under full and under partial observability; the best value of each column in bold. Runs
that have not finished show ``n/a``. The sweep calls this itself when every run is done.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from radar2shape.reporting import Column, markdown_table, write_csv
from radar2shape.sweep import is_done, load_grid

METRICS = [("iou_r", "IoU-R ↑", True), ("iou_s", "IoU-S ↑", True), ("match_s", "MATCH-S ↓", False)]
NAMES = {"unet": "Profile U-Net diffusion (ours)", "invrt": "InvRT", "full": "Full", "partial": "Partial"}
NOISE_DB = {"low": -80, "medium": -60, "high": -40}


def columns(observabilities: list[str]) -> list[Column]:
    return [Column(f"{obs}_{key}", f"{NAMES.get(obs, obs)} {header}", better)
            for obs in observabilities for key, header, better in METRICS]


def collect(grid_path: str | Path) -> tuple[dict, dict, dict[str, float]]:
    """``(axes, results, seconds)``: axis value names, ``results[noise][model][f"{obs}_{metric}_{mean|std}"]``,
    wall seconds per finished run."""
    grid = load_grid(grid_path)
    axes = {"model": [], "obs": [], "noise": []}
    results: dict = {}
    seconds: dict[str, float] = {}
    for run in grid.runs:
        model, obs, noise = run.name.split("-")
        for axis, value in zip(axes, (model, obs, noise)):
            if value not in axes[axis]:
                axes[axis].append(value)
        row = results.setdefault(noise, {}).setdefault(model, {})
        run_dir = grid.run_dir(run)
        if not is_done(run_dir):
            continue
        seconds[run.name] = json.loads((run_dir / "done").read_text())["wall_seconds"]
        metrics = json.loads((run_dir / "metrics.json").read_text())
        for key, _, _ in METRICS:
            for stat in ("mean", "std"):
                if f"{key}_{stat}" in metrics:
                    row[f"{obs}_{key}_{stat}"] = metrics[f"{key}_{stat}"]
    return axes, results, seconds


def noise_title(noise: str) -> str:
    level = NOISE_DB.get(noise)
    return f"{noise.capitalize()} noise ({level} dB)" if level is not None else noise


def build_table(grid_path: str | Path, out_dir: str | Path) -> str:
    """Write ``table.md`` and ``table.csv`` under ``out_dir``; returns the Markdown."""
    axes, results, seconds = collect(grid_path)
    cols = columns(axes["obs"])
    sections, csv_rows = [], []
    for noise in axes["noise"]:
        rows = [(NAMES.get(model, model), results[noise][model]) for model in axes["model"]]
        sections.append(f"### {noise_title(noise)}\n\n{markdown_table(rows, cols)}")
        csv_rows += [(f"{noise}/{model}", results[noise][model]) for model in axes["model"]]
    total = sum(seconds.values())
    n_runs = len(axes["model"]) * len(axes["obs"]) * len(axes["noise"])
    text = "\n\n".join(
        [f"## Roll-symmetric reconstruction ({Path(grid_path).name})",
         "Test-set mean ± std. IoU-R: radar IoU at 20 dB below peak; IoU-S: half-section IoU; "
         "MATCH-S: mean matched-point distance (unit-cube units). Definitions: docs/rollsym.md.",
         *sections,
         f"{len(seconds)} of {n_runs} runs finished; summed wall time of the runs {total / 60:.1f} min "
         "(fit + test, excluding the data build)."]
    ) + "\n"
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "table.md").write_text(text)
    write_csv(csv_rows, cols, out_dir / "table.csv")
    (out_dir / "wall_seconds.json").write_text(json.dumps(seconds, indent=2))
    return text


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", default="conf/grid/rollsym.yaml", help="the grid file the sweep ran")
    parser.add_argument("--out", help="output folder (default reports/<grid name>)")
    args = parser.parse_args(argv)
    print(build_table(args.grid, args.out or Path("reports") / Path(args.grid).stem))
    return 0


if __name__ == "__main__":
    sys.exit(main())
