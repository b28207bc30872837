"""Run a grid of experiments one after another: ``python -m radar2shape.sweep conf/grid/NAME.yaml``.

A grid file lists runs; each run is ``fit`` then (optionally) ``test`` through
:func:`radar2shape.cli.main`, so a run is exactly what a person would type; a run with
``command: test`` only tests (models that train nothing, or a trained checkpoint on other test data
through a ``ckpt_path`` override). Every run owns a folder ``<out_dir>/<name>/`` holding the
command it ran (``run.yaml``), the Lightning logs, config and checkpoint (``fit/``, ``test/``), the
test metrics (``metrics.json``) and, written last and atomically, a ``done`` marker. Rerunning the
grid skips runs with a ``done`` marker and restarts any other run from scratch, so a killed sweep
resumes at the run it was in.

Dependencies are paths: an override value under ``<out_dir>/<other run>/`` (a Stage-1 or PO
checkpoint) makes the run depend on ``<other run>``, which must come earlier in the file (runs
execute in file order). A run whose dependency is not done fails with a one-line error. A finished
run is redone when a dependency finished after it (the dependency was redone) or when its
command in the grid changed (``run.yaml`` holds the arguments it ran with).

Grid file (YAML)::

    out_dir: runs/NAME                 # required
    configs: [conf/experiment/a.yaml]  # --config files for every run, in order
    overrides: {trainer.max_epochs: 5} # --key=value for every run
    test: true                         # run `test` on the last checkpoint (default true)
    threads: 1                         # optional: torch CPU threads (a busy machine runs faster with 1)
    prepare:                           # optional: radar2shape commands run first, every time
      - [build-data, --config, conf/data/x.yaml, --out, data/x]   #   (so they must resume cheaply)
    report: scripts/table.py           # optional: `python SCRIPT --grid GRID_FILE` after the runs
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

import argparse
import itertools
import json
import os
import re
import shutil
import subprocess
import sys
import time
import traceback
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from radar2shape.errors import UserInputError

DONE = "done"
_NAME = re.compile(r"^[A-Za-z0-9_.=+-]+$")
_GRID_KEYS = {"out_dir", "configs", "overrides", "test", "threads", "prepare", "report", "matrix", "runs"}
_PART_KEYS = {"configs", "overrides"}
COMMANDS = ("fit", "test")


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
    """A parsed grid file."""

    path: Path
    out_dir: Path
    runs: list[Run]
    test: bool = True
    prepare: list[list[str]] = field(default_factory=list)
    report: str | None = None
    threads: int | None = None

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


def _part(spec, where: str, extra_keys: frozenset = frozenset({"name"})) -> tuple[list[str], dict]:
    """The ``configs`` and ``overrides`` of one grid entry, checked (``extra_keys`` are read by the caller)."""
    spec = spec or {}
    if not isinstance(spec, dict) or set(spec) - _PART_KEYS - extra_keys:
        raise UserInputError(f"{where}: expected a mapping with keys {sorted(_PART_KEYS | extra_keys)}, got {spec!r}")
    configs = spec.get("configs") or []
    overrides = spec.get("overrides") or {}
    if not isinstance(configs, list) or not isinstance(overrides, dict):
        raise UserInputError(f"{where}: 'configs' must be a list and 'overrides' a mapping")
    return [str(c) for c in configs], dict(overrides)


def _matrix_runs(matrix: dict, where: str) -> list[Run]:
    """Cartesian product of the matrix axes, in file order; later axes override earlier ones."""
    if not isinstance(matrix, dict) or not all(isinstance(v, dict) and v for v in matrix.values()):
        raise UserInputError(f"{where}: 'matrix' must map each axis to a non-empty mapping of named values")
    runs = []
    for combo in itertools.product(*(list(axis.items()) for axis in matrix.values())):
        run = Run(name="-".join(str(name) for name, _ in combo))
        for (value_name, spec), axis in zip(combo, matrix):
            configs, overrides = _part(spec, f"{where}: matrix.{axis}.{value_name}")
            run.configs += configs
            run.overrides.update(overrides)
        runs.append(run)
    return runs


def load_grid(path: str | Path) -> Grid:
    """Parse and check a grid file; raises :class:`UserInputError` naming the problem."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"grid file not found: {path}")
    spec = yaml.safe_load(path.read_text()) or {}
    if not isinstance(spec, dict) or "out_dir" not in spec:
        raise UserInputError(f"{path}: expected a mapping with at least 'out_dir'")
    unknown = set(spec) - _GRID_KEYS
    if unknown:
        raise UserInputError(f"{path}: unknown keys {sorted(unknown)}; allowed: {sorted(_GRID_KEYS)}")
    configs, overrides = _part({k: spec.get(k) for k in _PART_KEYS}, str(path))
    runs = _matrix_runs(spec["matrix"], str(path)) if spec.get("matrix") else []
    for i, entry in enumerate(spec.get("runs") or []):
        if not isinstance(entry, dict) or "name" not in entry:
            raise UserInputError(f"{path}: runs[{i}] needs a 'name'")
        run_configs, run_overrides = _part(entry, f"{path}: runs[{i}]", frozenset({"name", "command"}))
        command = entry.get("command", "fit")
        if command not in COMMANDS:
            raise UserInputError(f"{path}: runs[{i}] ({entry['name']}): command must be one of {list(COMMANDS)}, got {command!r}")
        runs.append(Run(str(entry["name"]), run_configs, run_overrides, command))
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
        run.configs = configs + run.configs
        run.overrides = {**overrides, **run.overrides}
    prepare = spec.get("prepare") or []
    if not isinstance(prepare, list) or not all(isinstance(c, list) and c for c in prepare):
        raise UserInputError(f"{path}: 'prepare' must be a list of commands, each a list like [build-data, --config, ...]")
    prepare = [[str(part) for part in command] for command in prepare]
    threads = spec.get("threads")
    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int) or threads < 1):
        raise UserInputError(f"{path}: 'threads' must be a positive integer, got {threads!r}")
    grid = Grid(path, Path(spec["out_dir"]), runs, bool(spec.get("test", True)), prepare, spec.get("report"), threads)
    for i, run in enumerate(runs):
        earlier = set(names[:i])
        for need in grid.needs(run):
            if need not in earlier:
                raise UserInputError(f"{path}: run {run.name!r} uses a path under {grid.out_dir / need}, "
                                     f"which is not a run listed before it (runs execute in file order)")
    return grid


def is_done(run_dir: Path) -> bool:
    return (run_dir / DONE).is_file()


def stale_because(grid: Grid, run: Run) -> str | None:
    """Why a finished run must be redone (the grid changed its command, or a dependency finished
    after it), else None."""
    run_dir = grid.run_dir(run)
    recorded = run_dir / "run.yaml"
    if recorded.is_file() and (yaml.safe_load(recorded.read_text()) or {}).get(run.command) != run.args(run_dir / run.command):
        return "its command in the grid changed"
    finished = (run_dir / DONE).stat().st_mtime_ns
    for need in grid.needs(run):
        marker = grid.out_dir / need / DONE
        if marker.is_file() and marker.stat().st_mtime_ns > finished:
            return f"{need} finished after it"
    return None


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _last_checkpoint(fit_dir: Path) -> Path:
    """``last.ckpt`` when saved, else the newest checkpoint under the fit logs."""
    checkpoints = sorted(fit_dir.rglob("*.ckpt"), key=lambda p: (p.name == "last.ckpt", p.stat().st_mtime))
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
    from radar2shape.cli import main

    code = main([command, *args])
    if code:
        raise RuntimeError(f"radar2shape {command} exited with code {code}")


def _test(run: Run, run_dir: Path, record: dict, extra: list[str]) -> None:
    """``test`` into ``run_dir/test``; its time and metrics go into ``record`` and ``metrics.json``."""
    start = time.perf_counter()
    _cli("test", run.args(run_dir / "test") + extra)
    record["test_seconds"] = round(time.perf_counter() - start, 2)
    metrics = _test_metrics(run_dir / "test")
    _write_atomic(run_dir / "metrics.json", json.dumps(metrics, indent=2, sort_keys=True))


def execute(grid: Grid, run: Run) -> dict:
    """Fit (and test) one run from scratch in its folder; returns what the ``done`` marker holds."""
    run_dir = grid.run_dir(run)
    if run_dir.exists():
        shutil.rmtree(run_dir)  # an unfinished run: its partial logs would confuse the next one
    run_dir.mkdir(parents=True)
    args = run.args(run_dir / run.command)
    _write_atomic(run_dir / "run.yaml", yaml.safe_dump({"name": run.name, "grid": str(grid.path), run.command: args}))
    record = {"name": run.name, "command": run.command}
    if run.command == "test":
        _test(run, run_dir, record, [])
        record["wall_seconds"] = record["test_seconds"]
        _write_atomic(run_dir / DONE, json.dumps(record, indent=2))
        return record
    start = time.perf_counter()
    _cli("fit", args)
    record["fit_seconds"] = round(time.perf_counter() - start, 2)
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
        _cli(command[0], command[1:])


def run_grid(grid: Grid, only: list[str] | None = None, keep_going: bool = False) -> int:
    """Run every unfinished run in order; returns the number of runs that failed."""
    unknown = sorted(set(only or []) - {r.name for r in grid.runs})
    if unknown:
        raise UserInputError(f"{grid.path}: no runs named {unknown}")
    runs = [r for r in grid.runs if not only or r.name in only]
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


def run_report(grid: Grid) -> None:
    """Run the grid's report script, if any, as ``python SCRIPT --grid GRID_FILE``."""
    if grid.report:
        subprocess.run([sys.executable, grid.report, "--grid", str(grid.path)], check=True)


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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m radar2shape.sweep", description=__doc__.splitlines()[0])
    parser.add_argument("grid", help="grid YAML file, e.g. conf/grid/rollsym.yaml")
    parser.add_argument("--only", nargs="+", help="run only these run names")
    parser.add_argument("--keep-going", action="store_true", help="continue after a failed run")
    parser.add_argument("--list", action="store_true", help="print each run's name and fit arguments, run nothing")
    parser.add_argument("--threads", type=int, help="torch CPU threads, overriding the grid's 'threads'")
    args = parser.parse_args(argv)
    try:
        grid = load_grid(args.grid)
        if args.list:
            for run in grid.runs:
                state = "todo" if not is_done(grid.run_dir(run)) or stale_because(grid, run) else "done"
                print(f"{run.name} [{state}]: {run.command} {' '.join(run.args(grid.run_dir(run) / run.command))}")
            return 0
        start = time.perf_counter()
        with torch_threads(args.threads or grid.threads):
            run_prepare(grid)
            failed = run_grid(grid, args.only, args.keep_going)
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    print(f"[sweep] grid finished in {time.perf_counter() - start:.1f} s, {failed} failed", flush=True)
    if not failed:
        run_report(grid)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
