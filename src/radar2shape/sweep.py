"""Grids of experiments: the schema of ``conf/grid/*.yaml`` and the resumable runner behind ``radar2shape sweep``.

A grid file lists runs; each run is ``fit`` then (optionally) ``test`` through
:func:`radar2shape.cli.main`, so a run is exactly what a person would type; a run with
``command: test`` only tests (models that train nothing, or a trained checkpoint on other test data
through a ``ckpt_path`` override). Every run owns a folder ``<out_dir>/<name>/`` holding the
command it ran (``run.yaml``), the Lightning logs, config and checkpoint (``fit/``, ``test/``), the
test metrics (``metrics.json``) and, written last and atomically, a ``done`` marker. Rerunning the
grid skips runs with a ``done`` marker, resumes a fit that was interrupted (killed, not failed) from
its last readable checkpoint when the grid still gives it the same command, and restarts any other
run from scratch: a killed sweep, or a two-hour run cut by the end of a sitting, loses at most the
epochs since the last checkpoint (one epoch with the shipped callbacks, which save every epoch).
A fit stopped by SIGTERM (see :mod:`radar2shape.preemption`) saves ``last.ckpt`` at the batch it
stopped, records no failure, and is resumed from there; the sweep itself then exits with
:data:`radar2shape.preemption.EXIT_CODE`. A parallel sweep passes the signal on to its runs.

Dependencies are paths: an override value under ``<out_dir>/<other run>/`` (a Stage-1 or PO
checkpoint) makes the run depend on ``<other run>``, which must come earlier in the file (runs
execute in file order). A run whose dependency is not done fails with a one-line error. A finished
run is redone when a dependency finished after it (the dependency was redone) or when its
command in the grid changed (``run.yaml`` holds the arguments it ran with).

Grid file (YAML, schema :class:`GridSpec`)::

    out_dir: runs/NAME                 # required
    configs: [conf/experiment/a.yaml]  # --config files for every run, in order
    overrides: {trainer.max_epochs: 5} # --key=value for every run
    test: true                         # run `test` on the last checkpoint of fit runs (default true)
    threads: 1                         # optional: torch CPU threads (a busy machine runs faster with 1)
    jobs: 2                            # optional: runs at once, each in its own process (default 1)
    prepare:                           # optional: radar2shape commands run first, every time
      - [build-data, --config, conf/data/x.yaml, --out, data/x]   #   (so they must resume cheaply)
    report: table1                     # optional: report layout (radar2shape.reporting.layouts) written
                                       #   after the runs; `radar2shape report` defaults to table1
    matrix:                            # optional: cartesian product; names joined with "-"
      model:                           #   axis -> value name -> {configs, overrides}
        unet: {overrides: {model: conf/model/profile_unet.yaml}}
      noise:
        low: {overrides: {data.init_args.noise_db: -80}}
    runs:                              # optional: explicit runs, after the matrix runs
      - {name: extra, configs: [...], overrides: {...}}
      - {name: ref, command: test, overrides: {model: pkg.Reference}}   # test only, no fit

An override's value may be a config file path (``model: conf/model/x.yaml``): jsonargparse loads it.
"""

from __future__ import annotations

import itertools
import json
import os
import re
import shutil
import sys
import time
import traceback
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import yaml

from radar2shape import preemption
from radar2shape.errors import UserInputError
from radar2shape.structured_config import read_yaml, structured

DONE = "done"
LOCK = ".sweep.lock"  # in out_dir: one sweep writes a grid's folders at a time (radar2shape.locking)
GRID_DIR = Path("conf/grid")
COMMANDS = ("fit", "test")
_NAME = re.compile(r"^[A-Za-z0-9_.=+-]+$")


@dataclass
class PartSpec:
    """What a matrix value adds to a run: ``--config`` files and ``--key=value`` overrides."""

    configs: list[str] = field(default_factory=list)
    overrides: dict[str, Any] = field(default_factory=dict)


@dataclass
class RunSpec(PartSpec):
    """An explicit run of a grid; ``command: test`` scores without fitting."""

    name: str = ""
    command: str = "fit"


@dataclass
class GridSpec:
    """The top level of a grid file. Matrix values and runs are checked one by one (see
    :func:`load_grid`) so an error names the entry it is in."""

    out_dir: str = "???"
    configs: list[str] = field(default_factory=list)
    overrides: dict[str, Any] = field(default_factory=dict)
    test: bool = True
    threads: Optional[int] = None
    jobs: int = 1
    prepare: list[list[Any]] = field(default_factory=list)
    report: Optional[str] = None
    matrix: dict[str, dict[str, Any]] = field(default_factory=dict)
    runs: list[Any] = field(default_factory=list)


@dataclass
class Run:
    """One experiment of a grid: its name, --config files and --key=value overrides."""

    name: str
    configs: list[str] = field(default_factory=list)
    overrides: dict = field(default_factory=dict)
    command: str = "fit"  # "test": score without fitting (nothing to train, or a given ckpt_path)

    def args(self, root_dir: Path) -> list[str]:
        """Lightning CLI arguments after the subcommand, logging under ``root_dir``."""
        args = [f"--config={c}" for c in self.configs]
        args += [f"--{key}={_format(value)}" for key, value in self.overrides.items()]
        return args + [f"--trainer.default_root_dir={root_dir}"]


@dataclass
class Grid:
    """A loaded and checked grid file."""

    path: Path
    out_dir: Path
    runs: list[Run]
    test: bool = True
    prepare: list[list[str]] = field(default_factory=list)
    report: str | None = None
    threads: int | None = None
    jobs: int = 1

    @property
    def name(self) -> str:
        return self.path.stem

    def run_dir(self, run: Run) -> Path:
        return self.out_dir / run.name

    def needs(self, run: Run) -> list[str]:
        """Names of the runs whose folders ``run``'s override values point into, in override order."""
        names = []
        for value in run.overrides.values():
            parts = Path(str(value)).parts
            prefix = self.out_dir.parts
            if len(parts) > len(prefix) and parts[: len(prefix)] == prefix and parts[len(prefix)] not in names:
                names.append(parts[len(prefix)])
        return names


def _format(value) -> str:
    """Scalars as YAML scalars (true, 0.1, text); lists and dicts as JSON, which jsonargparse parses."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return "null" if value is None else str(value)


def grid_path(grid: str | Path) -> Path:
    """A grid name (``table1`` -> ``conf/grid/table1.yaml``) or a YAML path, which must exist."""
    path = Path(grid)
    if path.suffix not in (".yaml", ".yml"):
        path = GRID_DIR / f"{grid}.yaml"
    if not path.is_file():
        raise UserInputError(f"grid file not found: {path} (give a name under {GRID_DIR}/ or a grid YAML file)")
    return path


def _matrix_runs(matrix: dict[str, dict[str, Any]], where: str) -> list[Run]:
    """Cartesian product of the matrix axes, in file order; later axes override earlier ones."""
    if not matrix:
        return []
    axes = []
    for axis, values in matrix.items():
        if not values:
            raise UserInputError(f"{where}: matrix.{axis}: expected a non-empty mapping of named values")
        axes.append([(name, structured(PartSpec, spec, f"{where}: matrix.{axis}.{name}")) for name, spec in values.items()])
    runs = []
    for combo in itertools.product(*axes):
        run = Run(name="-".join(str(name) for name, _ in combo))
        for _, part in combo:
            run.configs += part.configs
            run.overrides.update(part.overrides)
        runs.append(run)
    return runs


def load_grid(grid: str | Path) -> Grid:
    """Read a grid (name or path) on :class:`GridSpec` and check what types cannot say: run names
    unique and path-safe, commands known, dependencies on earlier runs, a known report layout."""
    path = grid_path(grid)
    spec = structured(GridSpec, read_yaml(path), str(path))
    runs = _matrix_runs(spec.matrix, str(path))
    for i, entry in enumerate(spec.runs):
        run = structured(RunSpec, entry, f"{path}: runs[{i}]")
        if not run.name:
            raise UserInputError(f"{path}: runs[{i}] needs a 'name'")
        if run.command not in COMMANDS:
            raise UserInputError(f"{path}: runs[{i}] ({run.name}): command must be one of {list(COMMANDS)}, got {run.command!r}")
        runs.append(Run(run.name, list(run.configs), dict(run.overrides), run.command))
    if not runs:
        raise UserInputError(f"{path}: no runs (give 'matrix' and/or 'runs')")
    names = [run.name for run in runs]
    for name in names:
        if not _NAME.match(name):
            raise UserInputError(f"{path}: run name {name!r} may use only letters, digits and . _ = + -")
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise UserInputError(f"{path}: duplicate run names {duplicates}")
    for run in runs:
        run.configs = list(spec.configs) + run.configs
        run.overrides = {**spec.overrides, **run.overrides}
    if any(not command for command in spec.prepare):
        raise UserInputError(f"{path}: key 'prepare': each command must be a non-empty list like [build-data, --config, ...]")
    if spec.threads is not None and spec.threads < 1:
        raise UserInputError(f"{path}: key 'threads': expected a positive integer, got {spec.threads}")
    if spec.jobs < 1:
        raise UserInputError(f"{path}: key 'jobs': expected a positive integer, got {spec.jobs}")
    if spec.report is not None:
        from radar2shape.reporting import LAYOUTS

        if spec.report not in LAYOUTS:
            raise UserInputError(f"{path}: key 'report': unknown report layout {spec.report!r} (expected one of {sorted(LAYOUTS)})")
    prepare = [[_format(part) for part in command] for command in spec.prepare]
    grid = Grid(path, Path(spec.out_dir), runs, spec.test, prepare, spec.report, spec.threads, spec.jobs)
    for i, run in enumerate(runs):
        earlier = set(names[:i])
        for need in grid.needs(run):
            if need not in earlier:
                raise UserInputError(f"{path}: run {run.name!r} uses a path under {grid.out_dir / need}, "
                                     f"which is not a run listed before it (runs execute in file order)")
    return grid


def is_done(run_dir: Path) -> bool:
    return (run_dir / DONE).is_file()


def recorded_args(run_dir: Path, command: str) -> list[str] | None:
    """The ``command`` arguments a run folder's ``run.yaml`` says it ran with (None without one)."""
    recorded = run_dir / "run.yaml"
    return (yaml.safe_load(recorded.read_text()) or {}).get(command) if recorded.is_file() else None


def stale_because(grid: Grid, run: Run) -> str | None:
    """Why a finished run must be redone (the grid changed its command, or a dependency finished
    after it), else None."""
    run_dir = grid.run_dir(run)
    recorded = recorded_args(run_dir, run.command)
    if recorded is not None and recorded != run.args(run_dir / run.command):
        return "its command in the grid changed"
    finished = (run_dir / DONE).stat().st_mtime_ns
    for need in grid.needs(run):
        marker = grid.out_dir / need / DONE
        if marker.is_file() and marker.stat().st_mtime_ns > finished:
            return f"{need} finished after it"
    return None


def _write_atomic(path: Path, text: str) -> None:
    from radar2shape.atomic import write_text_atomic

    write_text_atomic(path, text)


def check_out_dir(grid: Grid) -> None:
    """Refuse, before any run starts, an ``out_dir`` that is a file or lies in a read-only folder."""
    from radar2shape.atomic import check_output_dir

    check_output_dir(grid.out_dir, f"{grid.path}: key 'out_dir'")


def _version(path: Path) -> int:
    """The Lightning log version (``version_N``) a file lies under, -1 if none."""
    numbers = [int(part[8:]) for part in path.parts if part.startswith("version_") and part[8:].isdigit()]
    return numbers[-1] if numbers else -1


def _last_checkpoint(fit_dir: Path) -> Path:
    """The newest log version's ``last.ckpt`` when saved, else its newest checkpoint (a resumed fit
    logs into a new version; the ``last.ckpt`` a SIGTERM left in the old one is not its result)."""
    checkpoints = sorted(fit_dir.rglob("*.ckpt"),
                         key=lambda p: (_version(p), p.name == "last.ckpt", p.stat().st_mtime))
    if not checkpoints:
        raise RuntimeError(f"fit wrote no checkpoint under {fit_dir}")
    return checkpoints[-1]


def _test_metrics(test_dir: Path) -> dict[str, float]:
    from radar2shape.reporting import read_logged_metrics

    files = sorted(test_dir.rglob("metrics.csv"), key=lambda p: p.stat().st_mtime)
    if not files:
        raise RuntimeError(f"test logged no metrics under {test_dir}")
    return read_logged_metrics(files[-1])


def _cli(command: str, args: list[str]) -> None:
    from radar2shape import cli

    with cli.errors_raised(), preemption.caller_reports():  # a failed run keeps its traceback in its folder
        code = cli.main([command, *args])
    preemption.raise_if_received()  # SIGTERM after the last batch: the command finished, the sweep stops
    if code:
        raise RuntimeError(f"radar2shape {command} exited with code {code}")


def _test(run: Run, run_dir: Path, record: dict, extra: list[str]) -> None:
    """``test`` into ``run_dir/test``; its time and metrics go into ``record`` and ``metrics.json``."""
    start = time.perf_counter()
    _cli("test", run.args(run_dir / "test") + extra)
    record["test_seconds"] = round(time.perf_counter() - start, 2)
    metrics = _test_metrics(run_dir / "test")
    _write_atomic(run_dir / "metrics.json", json.dumps(metrics, indent=2, sort_keys=True))


def resumable_checkpoint(run: Run, run_dir: Path) -> Path | None:
    """The newest readable ``last.ckpt`` of an interrupted fit that ran ``run``'s current command,
    else None (no fit, a recorded failure, another command, no or a truncated checkpoint)."""
    from radar2shape.checkpoints import load_checkpoint

    if run.command != "fit" or (run_dir / "failed").is_file():
        return None
    if recorded_args(run_dir, "fit") != run.args(run_dir / "fit"):
        return None
    for checkpoint in sorted((run_dir / "fit").rglob("last.ckpt"), key=lambda p: p.stat().st_mtime, reverse=True):
        try:
            load_checkpoint(checkpoint, "a Lightning checkpoint")
        except UserInputError:  # cut while being written
            continue
        return checkpoint
    return None


def execute(grid: Grid, run: Run) -> dict:
    """Fit (and test) one run in its folder, resuming an interrupted fit (:func:`resumable_checkpoint`),
    else from scratch; returns what the ``done`` marker holds."""
    run_dir = grid.run_dir(run)
    resume = resumable_checkpoint(run, run_dir) if run_dir.exists() else None
    args = run.args(run_dir / run.command)
    record = {"name": run.name, "command": run.command}
    if resume is not None:
        record["resumed_from"] = str(resume.relative_to(run_dir))
        shutil.rmtree(run_dir / "test", ignore_errors=True)  # a test cut short: its files would mix with the new one
        print(f"[sweep] {run.name}: resuming from {resume}", flush=True)
    else:
        if run_dir.exists():
            (run_dir / DONE).unlink(missing_ok=True)  # first: a report reading meanwhile sees an unfinished run
            shutil.rmtree(run_dir)  # an unfinished run: its partial logs would confuse the next one
        run_dir.mkdir(parents=True)
        _write_atomic(run_dir / "run.yaml", yaml.safe_dump({"name": run.name, "grid": str(grid.path), run.command: args}))
    if run.command == "test":
        _test(run, run_dir, record, [])
        record["wall_seconds"] = record["test_seconds"]
        _write_atomic(run_dir / DONE, json.dumps(record, indent=2))
        return record
    start = time.perf_counter()
    _cli("fit", args + ([f"--ckpt_path={resume}"] if resume is not None else []))
    record["fit_seconds"] = round(time.perf_counter() - start, 2)  # of this sitting when resumed
    checkpoint = _last_checkpoint(run_dir / "fit")
    record["checkpoint"] = str(checkpoint.relative_to(run_dir))
    if grid.test:
        _test(run, run_dir, record, [f"--ckpt_path={checkpoint}"])
    record["wall_seconds"] = round(record["fit_seconds"] + record.get("test_seconds", 0.0), 2)
    _write_atomic(run_dir / DONE, json.dumps(record, indent=2))
    return record


def run_prepare(grid: Grid) -> None:
    """Run the grid's ``prepare`` commands (``radar2shape`` subcommands) in order."""
    for command in grid.prepare:
        print(f"[sweep] prepare: radar2shape {' '.join(command)}", flush=True)
        try:
            _cli(command[0], command[1:])
        except preemption.Preempted as stop:
            stop.detail = stop.detail or f"prepare step radar2shape {' '.join(command)}"
            raise


def select_runs(grid: Grid, only: list[str] | None) -> list[Run]:
    """The grid's runs, or those named in ``only`` (an unknown name is an error)."""
    unknown = sorted(set(only or []) - {r.name for r in grid.runs})
    if unknown:
        raise UserInputError(f"{grid.path}: no runs named {unknown}")
    return [r for r in grid.runs if not only or r.name in only]


def run_grid(grid: Grid, only: list[str] | None = None, keep_going: bool = False) -> int:
    """Run every unfinished run in order; returns the number of runs that failed."""
    runs = select_runs(grid, only)
    failed = 0
    for i, run in enumerate(runs, 1):
        run_dir = grid.run_dir(run)
        stale = stale_because(grid, run) if is_done(run_dir) else None
        if is_done(run_dir) and not stale:
            print(f"[sweep] {i}/{len(runs)} {run.name}: done, skipped", flush=True)
            continue
        print(f"[sweep] {i}/{len(runs)} {run.name}: {'redone, ' + stale if stale else 'running'} in {run_dir}", flush=True)
        missing = [need for need in grid.needs(run) if not is_done(grid.out_dir / need)]
        if missing:
            failed += 1
            print(f"[sweep] {run.name}: FAILED: needs {missing}, not done (run those first)", file=sys.stderr, flush=True)
            if not keep_going:
                break
            continue
        try:
            record = execute(grid, run)
        except preemption.Preempted as stop:  # not a failure: the run stays resumable
            stop.detail = stop.detail or f"run {run.name}" + (f" (saved {stop.checkpoint})" if stop.checkpoint else "")
            raise
        except Exception:
            failed += 1
            run_dir.mkdir(parents=True, exist_ok=True)
            _write_atomic(run_dir / "failed", traceback.format_exc())
            print(f"[sweep] {run.name}: FAILED (traceback in {run_dir / 'failed'})", file=sys.stderr, flush=True)
            if not keep_going:
                raise
            continue
        print(f"[sweep] {run.name}: finished in {record['wall_seconds']:.1f} s", flush=True)
    return failed


def _ready(grid: Grid, run: Run, waiting: set[str]) -> bool:
    """A run may start once none of its dependencies is still waiting or running."""
    return not set(grid.needs(run)) & waiting


def run_grid_parallel(grid: Grid, runs: list[Run], jobs: int, keep_going: bool, threads: int | None) -> int:
    """Up to ``jobs`` runs at once, each a child process running exactly one run
    (:func:`child_main`), started in file order once its dependencies have finished. A child's output
    goes to ``<out_dir>/<run>.log``; the resume and redo rules are those of :func:`run_grid`.
    Returns the number of runs that failed.

    SIGTERM (to this process, or a run ending with :data:`radar2shape.preemption.EXIT_CODE`) is
    passed on to every running run, which saves its checkpoint; once all have ended the sweep
    raises :class:`radar2shape.preemption.Preempted`."""
    import subprocess

    todo = []
    for run in runs:
        run_dir = grid.run_dir(run)
        stale = stale_because(grid, run) if is_done(run_dir) else None
        if is_done(run_dir) and not stale:
            print(f"[sweep] {run.name}: done, skipped", flush=True)
        else:
            todo.append(run)
    waiting, running, failed = {r.name for r in todo}, {}, 0
    grid.out_dir.mkdir(parents=True, exist_ok=True)
    code = ("import sys; from radar2shape.sweep import child_main; "
            "sys.exit(child_main(sys.argv[1], sys.argv[2], int(sys.argv[3])))")
    stop = False
    try:
        return _parallel_loop(grid, todo, jobs, keep_going, threads, waiting, running, code, failed, stop)
    except preemption.Preempted as preempted:
        cut = _stop_children(running)
        preempted.detail = f"runs {', '.join(sorted(cut))}" if cut else None
        raise


def _stop_children(running: dict) -> list[str]:
    """SIGTERM to every running child, then wait for all (they save their checkpoints); their names."""
    import signal

    for process in running.values():
        if process.poll() is None:
            try:
                os.kill(process.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
    for process in running.values():
        while True:
            try:
                process.wait()
                break
            except preemption.Preempted:  # a further SIGTERM: still wait for the checkpoints
                continue
    return list(running)


def _parallel_loop(grid, todo, jobs, keep_going, threads, waiting, running, code, failed, stop) -> int:
    import subprocess

    while (todo and not stop) or running:
        for run in [r for r in todo if not stop and len(running) < jobs and _ready(grid, r, waiting - {r.name})]:
            if len(running) >= jobs:
                break
            todo.remove(run)
            missing = [need for need in grid.needs(run) if not is_done(grid.out_dir / need)]
            if missing:
                failed += 1
                waiting.discard(run.name)
                print(f"[sweep] {run.name}: FAILED: needs {missing}, not done", file=sys.stderr, flush=True)
                stop = not keep_going
                continue
            log = grid.run_dir(run).with_suffix(".log")
            print(f"[sweep] {run.name}: running in {grid.run_dir(run)} (log {log})", flush=True)
            with log.open("w") as handle:
                running[run.name] = subprocess.Popen(
                    [sys.executable, "-c", code, str(grid.path), run.name, str(threads or 0)],
                    stdout=handle, stderr=subprocess.STDOUT)
        time.sleep(0.5)
        for name, process in list(running.items()):
            if process.poll() is None:
                continue
            if process.returncode in (preemption.EXIT_CODE, -preemption.signal.SIGTERM):  # stopped by SIGTERM
                raise preemption.Preempted()
            del running[name]
            waiting.discard(name)
            if process.returncode == 0:
                print(f"[sweep] {name}: finished", flush=True)
                continue
            failed += 1
            print(f"[sweep] {name}: FAILED (see {grid.out_dir / name / 'failed'})", file=sys.stderr, flush=True)
            stop = stop or not keep_going
    return failed


def child_main(grid_path: str, name: str, threads: int) -> int:
    """One run of a parallel sweep, in its own process (1 when it failed: its folder says why)."""
    grid = load_grid(grid_path)
    with preemption.sigterm_stops(), preemption.caller_reports(), torch_threads(threads or None):
        try:
            return run_grid(grid, [name], keep_going=True)
        except Exception:  # noqa: BLE001 - run_grid already wrote the traceback to the run's folder
            return 1


def run_report(grid: Grid) -> None:
    """Write the grid's report layout, if it names one, to ``reports/<grid name>/``."""
    if grid.report:
        from radar2shape.reporting import write_report

        print(f"[sweep] report: {write_report(grid)}", flush=True)


@contextmanager
def torch_threads(threads: int | None):
    """Run with ``threads`` torch CPU threads (None: unchanged), restoring the previous count."""
    if not threads:
        yield
        return
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        yield
    finally:
        torch.set_num_threads(previous)
