"""Benchmark: start-up wall time of the ``radar2shape`` console script, per command.

    python bench/cli.py [--repeat 3] [--commands evaluate simulate]

Runs ``radar2shape --version``, ``radar2shape --help`` and ``radar2shape CMD --help`` for every
command in a fresh subprocess ``repeat`` times and prints the median wall time, plus whether the
process imported Lightning and torch: a user who scores a folder of meshes pays the start-up per
file, so tool commands that do not need them must not import them. The package is imported from
``$PYTHONPATH`` first when set (how an older checkout is measured), else from this checkout.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
COMMANDS = ["fit", "validate", "test", "predict", "simulate", "build-data", "reconstruct", "evaluate", "sweep", "report"]

# Runs the console script in-process and reports, at exit, which heavy modules it had imported.
CHILD = """
import atexit, sys
atexit.register(lambda: sys.stderr.write("BENCH_MODULES lightning=%d torch=%d\\n"
                % ("lightning" in sys.modules, "torch" in sys.modules)))
sys.argv = ["radar2shape", *sys.argv[1:]]
from radar2shape.cli import entrypoint
entrypoint()
"""


def child_env() -> dict[str, str]:
    """``$PYTHONPATH`` (if any) before this checkout's ``src`` and root, and wandb silenced."""
    env = dict(os.environ, WANDB_MODE="disabled", WANDB_SILENT="true")
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p] + [str(REPO / "src"), str(REPO)]
    env["PYTHONPATH"] = os.pathsep.join(paths)
    return env


def time_once(argv: list[str], env: dict[str, str]) -> tuple[float, str, int]:
    """Wall seconds of one start, the modules line the child printed, and its exit code."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", CHILD, *argv], env=env, cwd=REPO, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    modules = next((line.split(" ", 1)[1] for line in done.stderr.splitlines() if line.startswith("BENCH_MODULES")), "?")
    return seconds, modules, done.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="starts per command; the median is printed")
    parser.add_argument("--commands", nargs="+", default=COMMANDS, help="commands whose --help is timed")
    args = parser.parse_args()
    env = child_env()
    cases = [["--version"], ["--help"]] + [[command, "--help"] for command in args.commands]
    print(f"{'command':<28} {'median s':>9} {'min s':>7}  imports")
    for argv in cases:
        runs = [time_once(argv, env) for _ in range(args.repeat)]
        times = [seconds for seconds, _, _ in runs]
        codes = sorted({code for _, _, code in runs})
        note = "" if codes == [0] else f"  (exit codes {codes})"
        print(f"{'radar2shape ' + ' '.join(argv):<28} {statistics.median(times):>9.2f} {min(times):>7.2f}  {runs[-1][1]}{note}",
              flush=True)


if __name__ == "__main__":
    main()
