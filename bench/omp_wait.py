"""Benchmark: how long OpenMP threads wait for work before sleeping, on a quiet and on a busy machine.

    python bench/omp_wait.py [--out reports/throughput/omp_wait.md] [--stage stage2] [--loads 0 2]

Between two parallel regions a libgomp thread spins ``GOMP_SPINCOUNT`` times before it sleeps
(``OMP_WAIT_POLICY=PASSIVE``: it sleeps at once; unset: libgomp's 300,000). Spinning keeps the
second core on the model when nothing else wants it; sleeping gives the core away when something
else does, and costs a wake-up at every region. Each line runs ``bench/fit_steps.py --fast-only``
(the table1-medium-fast fit, seconds per step, no validation) in a fresh process with one setting,
beside ``load`` busy processes (pure Python loops) that stand for other jobs on the cores.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from fit_steps import FAST, missing_data, write_table  # noqa: E402
# (label, environment of the fit); every line names its variables, so the package's default
# (src/radar2shape/__init__.py sets them only when the environment does not) is one of these lines.
SETTINGS = [
    ("OMP_WAIT_POLICY=PASSIVE (sleep at once)", {"OMP_WAIT_POLICY": "PASSIVE"}),
    ("GOMP_SPINCOUNT=10000", {"GOMP_SPINCOUNT": "10000"}),
    ("GOMP_SPINCOUNT=100000", {"GOMP_SPINCOUNT": "100000"}),
    ("GOMP_SPINCOUNT=300000 (libgomp's default)", {"GOMP_SPINCOUNT": "300000"}),
]
BUSY = "while True: pass"
STEP_LINE = re.compile(rf"^\| (\w+) \| .*{re.escape(FAST)} \| ([0-9.]+) \|", re.M)


def time_setting(stage: str, env: dict[str, str], load: int, args: argparse.Namespace) -> float:
    """Seconds per step of the fast fit under ``env`` beside ``load`` busy processes."""
    child_env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    child_env.update(env)
    busy = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(load)]
    try:
        done = subprocess.run([sys.executable, str(REPO / "bench/fit_steps.py"), "--fast-only", "--stages", stage,
                               "--skip", str(args.skip), "--steps", str(args.steps), "--threads", str(args.threads)],
                              env=child_env, capture_output=True, text=True)
    finally:
        for process in busy:
            process.kill()
            process.wait()
    found = STEP_LINE.search(done.stdout)
    if done.returncode != 0 or found is None:
        raise RuntimeError(f"fit_steps failed under {env} (exit {done.returncode}): {done.stderr[-1500:]}")
    return float(found.group(2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stage", default="stage2", choices=["stage1", "stage2"])
    parser.add_argument("--loads", type=int, nargs="+", default=[0, 2], help="busy processes beside the fit")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--skip", type=int, default=20)
    parser.add_argument("--steps", type=int, default=80)
    parser.add_argument("--out", type=Path, default=None, help="also write the table here (markdown)")
    args = parser.parse_args()
    if missing_data("omp_wait", REPO / "data/parts_medium"):
        return
    header = " | ".join(f"{load} busy: s/step" for load in args.loads)
    lines = [f"The table1-medium-fast {args.stage} fit, {args.threads} threads, {os.cpu_count()} cores, steps "
             f"{args.skip}-{args.skip + args.steps} (`python bench/omp_wait.py`); busy: pure-Python loops beside it.", "",
             f"| OpenMP setting | {header} |", "|---|" + "---|" * len(args.loads)]
    for label, env in SETTINGS:
        cells = [f"{time_setting(args.stage, env, load, args):.3f}" for load in args.loads]
        lines.append(f"| {label} | {' | '.join(cells)} |")
        print(lines[-1], flush=True)
    write_table(lines, args.out)


if __name__ == "__main__":
    main()
