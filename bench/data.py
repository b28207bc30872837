"""Benchmark: dataset records per second for the default ``parts`` config, radar included.

    python bench/data.py [--num 12] [--workers 2] [--config conf/data/parts.yaml]

Builds ``num`` records into a temporary folder with ``workers`` processes and prints the rate;
worker start-up (imports) is included, as in a real build. Target: >= 1 record/s on 2 cores.
Also prints the CPU seconds per record (this process + its workers), which stays meaningful
on a shared machine where wall-clock rates depend on the load.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO)]

from data_modules.build import build_dataset  # noqa: E402
from data_modules.config import load_build_config  # noqa: E402


def _cpu_seconds() -> float:
    """User + system CPU time of this process and of its finished children (the workers)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default=str(REPO / "conf/data/parts.yaml"))
    parser.add_argument("--num", type=int, default=12)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    config = load_build_config(args.config, num=args.num)
    with tempfile.TemporaryDirectory() as folder:
        start, cpu_start = time.perf_counter(), _cpu_seconds()
        summary = build_dataset(config, folder, workers=args.workers, progress=False)
        seconds, cpu = time.perf_counter() - start, _cpu_seconds() - cpu_start
        size = sum(p.stat().st_size for p in Path(folder).rglob("*.npz")) / max(summary.built, 1)
    built = max(summary.built, 1)
    print(f"data build ({Path(args.config).name}, {args.workers} workers): {summary.built} records in {seconds:.1f} s "
          f"= {summary.built / seconds:.2f} records/s; {cpu / built:.2f} CPU s/record incl. worker start-up "
          f"({summary.skipped} skipped, {size / 1e6:.1f} MB/record)")


if __name__ == "__main__":
    main()
