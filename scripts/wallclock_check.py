"""Validation IoU against wall time: the medium Stage 1 and Stage 2 for a few minutes, on a GPU or a CPU.

    python scripts/wallclock_check.py --out DIR [--minutes 4] [--data data/parts_medium] [--workers 16] [--fit-args "..."]

What it runs, in order:
1. ``build-data`` of ``conf/data/parts_medium.yaml`` into ``--data`` when that holds no manifest;
2. ``bench/train_throughput.py --device DEVICE --bf16`` (shapes/s of each path) -> ``DIR/bench.txt``;
3. side by side on the one device (``--sequential``: one after another, for a CPU), each for
   ``--minutes`` of wall time: the table1-medium grid's own fits (``conf/grid/table1-medium.yaml``,
   its trainer layer swapped for ``conf/trainer/gpu.yaml`` on a GPU), Stage 1 (``radar2shape_stage1``)
   in float32 and in ``bf16-mixed``, and Stage 2 (``radar2shape-full-seed0``) in ``bf16-mixed`` on the
   Stage 1 given by ``--stage1-ckpt`` (default: the shipped model, whose Stage 1 a Stage-2 fit takes). Run
   names are ``stage1-`` or ``stage2-`` and end in ``fp32`` (float32) or ``bf16`` (``bf16-mixed``).
While they run, the wall time of each new validation row is noted, so ``DIR/wallclock_check.md`` can give
validation IoU against steps and seconds, and the step and second at which it first reaches the CPU
run's final validation IoU (``reports/table1-medium/learning_curves.md``).
"""

from __future__ import annotations

import argparse
import csv
import os
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "src/radar2shape/weights/radar2shape_parts_medium.ckpt"
sys.path[:0] = [str(REPO / "src"), str(REPO)]

CPU_CURVES = REPO / "reports/table1-medium/learning_curves.md"
CLI = [sys.executable, "-c", "from radar2shape.cli import entrypoint; entrypoint()"]
GRID_RUNS = {"stage1": "radar2shape_stage1", "stage2": "radar2shape-full-seed0"}  # what each check repeats


def cpu_final(run: str) -> tuple[int, float]:
    """(step, val IoU) of the last validation row of ``run`` in the committed CPU learning curves."""
    section = CPU_CURVES.read_text().split(f"## {run}\n", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| (\d+) \| (\d+) \| ([0-9.]+) \|", section, flags=re.M)
    return int(rows[-1][1]), float(rows[-1][2])


def fit_command(name: str, precision: str, args: argparse.Namespace, stage1_ckpt: Path) -> list[str]:
    """The table1-medium grid's own fit of ``name``'s stage, on this device, for ``--minutes``."""
    from radar2shape.sweep import load_grid

    stage = name.split("-")[0]
    run = next(r for r in load_grid("table1-medium").runs if r.name == GRID_RUNS[stage])
    fit_args = run.args(args.out / "runs" / name)
    if args.accelerator == "gpu":
        fit_args = [a.replace("conf/trainer/cpu.yaml", "conf/trainer/gpu.yaml") for a in fit_args]
    seconds = int(args.minutes * 60)
    overrides = {"trainer.precision": precision, "trainer.max_time": f"00:00:{seconds // 60:02d}:{seconds % 60:02d}",
                 "trainer.accelerator": args.accelerator, "data.init_args.root": args.data,
                 "data.init_args.num_workers": args.loader_workers}
    if stage == "stage2":
        overrides["model.init_args.stage1_ckpt"] = stage1_ckpt
    return CLI + ["fit", *fit_args, *(f"--{k}={v}" for k, v in overrides.items()), *args.extra]


def validation_rows(run_dir: Path) -> list[dict]:
    rows = []
    for path in run_dir.glob("**/metrics.csv"):
        with open(path, newline="") as handle:
            rows += [r for r in csv.DictReader(handle) if r.get("val/iou_mean")]
    return rows


def watch(runs: dict[str, subprocess.Popen], dirs: dict[str, Path], start: float) -> dict[str, list[tuple]]:
    """Poll each run's metrics.csv until every run exits; (epoch, step, IoU, seconds) per validation row."""
    seen: dict[str, dict] = {name: {} for name in runs}
    while True:
        done = all(p.poll() is not None for p in runs.values())
        for name in runs:
            for row in validation_rows(dirs[name]):
                seen[name].setdefault(int(row["step"]), (int(row["epoch"]), int(row["step"]),
                                                         float(row["val/iou_mean"]), time.perf_counter() - start))
        if done:
            return {name: sorted(rows.values(), key=lambda r: r[1]) for name, rows in seen.items()}
        time.sleep(2)


def summary(bench: str, curves: dict[str, list[tuple]], codes: dict[str, int], args: argparse.Namespace) -> str:
    lines = [f"# Medium Stage 1 / Stage 2 on {args.device_name}", "",
             f"`python scripts/wallclock_check.py {' '.join(args.argv)}` (scripts/wallclock_check.py). Device: {args.device_name}. "
             + ("The fits ran one after another" if args.sequential else "The fits ran side by side on the one device")
             + f", each with its own data loader ({args.loader_workers} worker processes).", ""]
    if bench:
        lines += ["## Training throughput (bench/train_throughput.py, synthetic medium batches)", "", "```", bench.strip(), "```", ""]
    for name, rows in curves.items():
        ref_step, ref_iou = cpu_final(GRID_RUNS[name.split("-")[0]])
        lines += [f"## {name} (exit {codes[name]})", "",
                  f"CPU run's final validation IoU: {ref_iou:.4f} at step {ref_step}.", "",
                  "| epoch | step | val/iou_mean | seconds since start |", "|---|---|---|---|"]
        lines += [f"| {e} | {s} | {iou:.4f} | {sec:.0f} |" for e, s, iou, sec in rows]
        passed = next((r for r in rows if r[2] >= ref_iou), None)
        lines += ["", f"Reaches the CPU final at step {passed[1]}, {passed[3]:.0f} s after start." if passed
                  else "Does not reach the CPU final within the run.", ""]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--minutes", type=float, default=4.0, help="wall time of each fit")
    parser.add_argument("--data", type=Path, default=REPO / "data/parts_medium")
    parser.add_argument("--workers", type=int, default=16, help="build-data workers")
    parser.add_argument("--loader-workers", type=int, default=4, help="DataLoader workers of each fit")
    parser.add_argument("--accelerator", default="gpu")
    parser.add_argument("--stage1-ckpt", type=Path, default=None)
    parser.add_argument("--runs", nargs="+", default=["stage1-fp32", "stage1-bf16", "stage2-bf16"])
    parser.add_argument("--bench-args", default="--models stage1 stage2 tmnet list", help="one string; '' skips the bench")
    parser.add_argument("--sequential", action="store_true", help="one fit after another (a CPU), each timed from its own start")
    parser.add_argument("--fit-args", default="", help="more arguments of every fit, one string")
    args = parser.parse_args()
    args.extra, args.argv = shlex.split(args.fit_args), [shlex.quote(a) for a in sys.argv[1:]]
    os.chdir(REPO)
    os.environ.setdefault("WANDB_MODE", "disabled")
    os.environ["PYTHONPATH"] = os.pathsep.join([str(REPO / "src"), str(REPO), os.environ.get("PYTHONPATH", "")])
    args.out.mkdir(parents=True, exist_ok=True)
    import torch

    device = "cuda" if args.accelerator == "gpu" else "cpu"
    args.device_name = torch.cuda.get_device_name(0) if device == "cuda" else f"CPU, {torch.get_num_threads()} threads"
    if not (args.data / "manifest.json").is_file():
        subprocess.run(CLI + ["build-data", "--config", "conf/data/parts_medium.yaml", "--out", str(args.data),
                        "--workers", str(args.workers), "--quiet"], check=True)
    print(f"data ready {time.strftime('%X')}", flush=True)
    bench_text = ""
    if args.bench_args:
        bench = subprocess.run([sys.executable, "bench/train_throughput.py", "--device", device, "--bf16",
                                *shlex.split(args.bench_args)], capture_output=True, text=True)
        bench_text = bench.stdout
        (args.out / "bench.txt").write_text(bench.stdout + bench.stderr[-3000:])
        print(bench.stdout, bench.stderr[-2000:], flush=True)
    stage1_ckpt = args.stage1_ckpt or SHIPPED  # Stage 2 starts from the shipped model's Stage 1
    dirs = {name: args.out / "runs" / name for name in args.runs}
    groups = [[name] for name in args.runs] if args.sequential else [args.runs]
    curves, codes = {}, {}
    for group in groups:
        start, runs = time.perf_counter(), {}
        for name in group:
            precision = "32" if name.endswith("fp32") else "bf16-mixed"
            with open(args.out / f"{name}.log", "w") as log:  # the child keeps its own handle
                runs[name] = subprocess.Popen(fit_command(name, precision, args, stage1_ckpt), stdout=log,
                                              stderr=subprocess.STDOUT)
        curves.update(watch(runs, dirs, start))
        codes.update({name: p.returncode for name, p in runs.items()})
    text = summary(bench_text, curves, codes, args)
    (args.out / "wallclock_check.md").write_text(text)
    print(text)
    return 0 if all(c == 0 for c in codes.values()) else 1


if __name__ == "__main__":
    raise SystemExit(main())
