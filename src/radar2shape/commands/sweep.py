"""``radar2shape sweep GRID``: run the runs of a grid that are not done yet, then its report.

GRID is a name under ``conf/grid/`` (``table1``, ``rollsym``, ``demo``) or a grid YAML file; the
grid format, resume and redo rules are described in :mod:`radar2shape.sweep`.
"""

from __future__ import annotations

import argparse
import time

from radar2shape import sweep
from radar2shape.errors import UserInputError


def configure_parser(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("grid", help="grid name (conf/grid/NAME.yaml) or a grid YAML file")
    parser.add_argument("--only", nargs="+", help="run only these run names")
    parser.add_argument("--keep-going", action="store_true", help="continue after a failed run")
    parser.add_argument("--list", action="store_true", help="print each run's state and arguments, run nothing")
    parser.add_argument("--threads", type=int, help="torch CPU threads, overriding the grid's 'threads'")
    parser.add_argument("--jobs", type=int, help="runs at once, each in its own process, overriding the grid's 'jobs'")


def main(args: argparse.Namespace) -> int:
    grid = sweep.load_grid(args.grid)
    if args.list:
        for run in grid.runs:
            run_dir = grid.run_dir(run)
            state = "todo" if not sweep.is_done(run_dir) or sweep.stale_because(grid, run) else "done"
            print(f"{run.name} [{state}]: {run.command} {' '.join(run.args(run_dir / run.command))}")
        return 0
    sweep.check_out_dir(grid)
    jobs = args.jobs or grid.jobs
    if jobs < 1:
        raise UserInputError(f"--jobs: expected a positive integer, got {jobs}")
    start = time.perf_counter()
    with sweep.torch_threads(args.threads or grid.threads):
        sweep.run_prepare(grid)
        if jobs > 1:
            failed = sweep.run_grid_parallel(grid, sweep.select_runs(grid, args.only), jobs, args.keep_going,
                                             args.threads or grid.threads)
        else:
            failed = sweep.run_grid(grid, args.only, args.keep_going)
    print(f"[sweep] grid finished in {time.perf_counter() - start:.1f} s, {failed} failed", flush=True)
    if failed:
        return 1
    sweep.run_report(grid)
    return 0
