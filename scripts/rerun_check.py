"""Rerun the first epochs of a finished fit and compare its training losses, step by step.

    python scripts/rerun_check.py --run runs/table1-medium/diffusion_sdf_stage1 [--epochs 2] \
        [--threads 1] [--out reports/table1-medium/rerun_check.md]

Reads the fit command the run recorded (``run.yaml``) and its log (``fit/version_0/metrics.csv``),
runs the same command for ``--epochs`` epochs into a temporary folder, and compares every
per-step training value (``train/*_step``) the two logs share. A rerun that matches bit for bit
says the grid's number is a function of its configuration on this machine; a drift says how far
threads, library versions or hardware move it. Exit code 0 when every value agrees within
``--rtol``, 1 when one does not, 2 on bad input. ``--twice`` compares two reruns with each other
instead of a rerun with the log, for a run whose log was written before a change to the code.
The learning-rate schedule must not depend on the number of epochs for the comparison to mean
anything (the step schedules of the shipped configs do not).
"""

from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from radar2shape.errors import UserInputError  # noqa: E402


def step_values(log: Path, epochs: int) -> dict[str, dict[int, float]]:
    """``{column: {step: value}}`` of the ``train/*_step`` columns logged in the first ``epochs`` epochs."""
    values: dict[str, dict[int, float]] = {}
    for row in csv.DictReader(log.open()):
        if int(row["epoch"]) >= epochs:
            continue
        for column, text in row.items():
            if column.startswith("train/") and column.endswith("_step") and text:
                values.setdefault(column, {})[int(row["step"])] = float(text)
    return values


def recorded_fit(run_dir: Path) -> tuple[list[str], Path]:
    """The run's recorded fit arguments and its first log, or a clear error."""
    from radar2shape.sweep import recorded_args

    args = recorded_args(run_dir, "fit")
    if not args:
        raise UserInputError(f"{run_dir / 'run.yaml'}: no recorded fit command (not a fitted run of a grid)")
    log = run_dir / "fit" / "version_0" / "metrics.csv"
    if not log.is_file():
        raise UserInputError(f"{log}: missing (the run has no training log)")
    return args, log


def rerun(args: list[str], epochs: int, threads: int, root: Path) -> Path:
    """Run the fit for ``epochs`` epochs under ``root`` with ``threads`` CPU threads; its metrics.csv."""
    kept = [a for a in args if not a.startswith(("--trainer.max_epochs=", "--trainer.default_root_dir="))]
    command = [sys.executable, "-m", "radar2shape.cli", "fit", *kept, f"--trainer.max_epochs={epochs}",
               f"--trainer.default_root_dir={root}", "--trainer.enable_progress_bar=false"]
    env = {**os.environ, "OMP_NUM_THREADS": str(threads), "MKL_NUM_THREADS": str(threads), "WANDB_MODE": "disabled"}
    done = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"the rerun failed (exit {done.returncode}): {last}")
    return root / "version_0" / "metrics.csv"


def compare(reference: dict[str, dict[int, float]], rerun_values: dict[str, dict[int, float]]) -> list[dict]:
    """Per column: steps compared, largest absolute and relative difference."""
    rows = []
    for column in sorted(reference):
        steps = sorted(set(reference[column]) & set(rerun_values.get(column, {})))
        diffs = [abs(reference[column][s] - rerun_values[column][s]) for s in steps]
        rels = [d / abs(reference[column][s]) if reference[column][s] else d for d, s in zip(diffs, steps)]
        rows.append({"column": column, "steps": len(steps), "max_abs": max(diffs, default=float("nan")),
                     "max_rel": max(rels, default=float("nan"))})
    return rows


def agrees(rows: list[dict], rtol: float) -> bool:
    """Every compared value has shared steps and no relative difference above ``rtol``."""
    return all(r["steps"] and r["max_rel"] <= rtol for r in rows)


def markdown(run_dir: Path, args: list[str], epochs: int, threads: int, rows: list[dict], rtol: float,
             twice: bool = False) -> str:
    agree = agrees(rows, rtol)
    against = "a second rerun" if twice else "its own log"
    lines = [f"# Rerun check: `{run_dir.name}`", "",
             f"The run's recorded fit command, rerun for its first {epochs} epoch(s) with {threads} CPU thread(s) "
             f"(`python scripts/rerun_check.py --run {run_dir} --epochs {epochs} --threads {threads}"
             f"{' --twice' if twice else ''}`), against {against}: every per-step training value both logs hold.", "",
             "```", "radar2shape fit " + " ".join(args), "```", "",
             "| logged value | steps compared | largest abs. difference | largest rel. difference |", "|---|---|---|---|"]
    lines += [f"| `{r['column']}` | {r['steps']} | {r['max_abs']:.3g} | {r['max_rel']:.3g} |" for r in rows]
    verdict = "bit for bit" if agree and all(r["max_abs"] == 0 for r in rows) else (
        f"within rtol {rtol:g}" if agree else f"NOT within rtol {rtol:g}")
    reproduced = "the second rerun reproduces the first" if twice else "the rerun reproduces the run's training"
    return "\n".join(lines + ["", f"Verdict: {reproduced} {verdict}.", ""])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, required=True, help="a fitted run folder of a grid (holds run.yaml)")
    parser.add_argument("--epochs", type=int, default=2, help="epochs to rerun and compare (default 2)")
    parser.add_argument("--threads", type=int, default=1, help="CPU threads of the rerun (default 1, as the grids)")
    parser.add_argument("--rtol", type=float, default=0.0, help="largest relative difference that agrees (default 0)")
    parser.add_argument("--out", type=Path, help="write the Markdown comparison here (default: print it)")
    parser.add_argument("--twice", action="store_true", help="compare two reruns with each other, not a rerun with the "
                        "run's log (a log written before a change to the code)")
    args = parser.parse_args(argv)
    try:
        if args.epochs < 1 or args.threads < 1:
            raise UserInputError(f"--epochs and --threads must be >= 1 (got {args.epochs}, {args.threads})")
        fit_args, log = recorded_fit(args.run)
        reference = step_values(log, args.epochs)
        if not reference:
            raise UserInputError(f"{log}: no train/*_step values in its first {args.epochs} epoch(s)")
        with tempfile.TemporaryDirectory(prefix="rerun_check_") as tmp:
            if args.twice:
                reference = step_values(rerun(fit_args, args.epochs, args.threads, Path(tmp) / "first"), args.epochs)
            rows = compare(reference, step_values(rerun(fit_args, args.epochs, args.threads, Path(tmp) / "rerun"), args.epochs))
    except (UserInputError, RuntimeError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    text = markdown(args.run, fit_args, args.epochs, args.threads, rows, args.rtol, args.twice)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
        print(f"wrote {args.out}")
    else:
        print(text)
    return 0 if agrees(rows, args.rtol) else 1


if __name__ == "__main__":
    sys.exit(main())
