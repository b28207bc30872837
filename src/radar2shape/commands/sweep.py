"""``radar2shape sweep GRID``: run the runs of a grid that are not done yet, then its report.

GRID is a name under ``conf/grid/`` (``table1``, ``rollsym``, ``demo``) or a grid YAML file; the
grid format, resume and redo rules are described in :mod:`radar2shape.sweep`.

One sweep writes a grid's ``out_dir`` at a time (a lock file, :mod:`radar2shape.locking`); a second
is refused with the holder's pid, host and start time. SIGTERM stops the sweep resumably
(:mod:`radar2shape.preemption`): one line, exit code 143, and the same command resumes.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time

from radar2shape import preemption, sweep
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
    from radar2shape.locking import folder_lock

    start = time.perf_counter()
    try:
        with preemption.sigterm_stops(), folder_lock(grid.out_dir, sweep.LOCK, "another sweep", "radar2shape sweep"), \
                sweep.torch_threads(args.threads or grid.threads):
            sweep.run_prepare(grid)
            if jobs > 1:
                failed = sweep.run_grid_parallel(grid, sweep.select_runs(grid, args.only), jobs, args.keep_going,
                                                 args.threads or grid.threads)
            else:
                failed = sweep.run_grid(grid, args.only, args.keep_going)
    except preemption.Preempted as stop:
        where = f" during {stop.detail}" if stop.detail else ""
        print(f"error: radar2shape sweep: stopped by SIGTERM{where}; rerun the same command to resume: "
              f"{shlex.join(_command(args))}", file=sys.stderr, flush=True)
        return preemption.EXIT_CODE
    print(f"[sweep] grid finished in {time.perf_counter() - start:.1f} s, {failed} failed", flush=True)
    if failed:
        return 1
    sweep.run_report(grid)
    return 0


def _command(args: argparse.Namespace) -> list[str]:
    """The command line that runs this sweep again."""
    command = ["radar2shape", "sweep", str(args.grid)]
    command += ["--only", *args.only] if args.only else []
    command += ["--keep-going"] if args.keep_going else []
    command += ["--threads", str(args.threads)] if args.threads else []
    command += ["--jobs", str(args.jobs)] if args.jobs else []
    return command
