"""Profile: where a training step's CPU time goes, per model, as one markdown table.

    python bench/profile_steps.py [--paths reference fast] [--models ...] [--threads 1] [--steps 2]

Per model at its medium config (synthetic batch of bench/train_throughput.py): CPU seconds per
step split into forward (losses), backward and optimizer (zero_grad + step) by process-time
timers; then one step under ``torch.profiler``: the three operators with the most self CPU time
(share of the operators' total), the operator calls per step and the share of the profiled time
outside operators (autograd engine, optimizer and Python glue: the per-op overhead).
Data loading is a separate line: the ShapeDataModule train loader in this process on
``data/parts_tiny`` records at the medium point counts (skipped without that folder).
One thread by default: with two OpenMP threads on oversubscribed cores the threads' spin-waiting
lands in whichever operator is running and the split says more about the load than the model.
docs/throughput.md holds the table this printed.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path[:0] = [str(Path(__file__).resolve().parent)]

import radar2shape  # noqa: E402,F401  (before torch: the package's OpenMP settings apply, as in a fit)
import torch  # noqa: E402
from torch.profiler import ProfilerActivity, profile  # noqa: E402
from train_throughput import BATCH, REPO, build, optimizer_of, path  # noqa: E402

from radar2shape.nn import kernels  # noqa: E402

MODELS = ["stage1", "stage2", "profile_unet", "invrt", "tmnet", "list"]


def phases(model: torch.nn.Module, batch: dict, steps: int) -> tuple[dict[str, float], dict]:
    """CPU seconds per step of forward, backward and optimizer, and the profiler's op table of one more step."""
    optimizer = optimizer_of(model)
    totals = {"forward": 0.0, "backward": 0.0, "optimizer": 0.0}

    def step(timed: bool) -> None:
        t0 = time.process_time()
        with kernels.training_autocast("cpu"):
            loss = model.losses(batch)["loss"]
        t1 = time.process_time()
        loss.backward()
        t2 = time.process_time()
        optimizer.step()
        optimizer.zero_grad(set_to_none=True)
        t3 = time.process_time()
        if timed:
            for key, seconds in zip(totals, (t1 - t0, t2 - t1, t3 - t2)):
                totals[key] += seconds / steps

    for _ in range(2):  # two warm-up steps: with one, the first model measured still paid one-time costs
        step(False)
    for _ in range(steps):
        step(True)
    with profile(activities=[ProfilerActivity.CPU]) as prof:
        step(False)
    events = prof.key_averages()
    ops = [e for e in events if e.key.startswith("aten::")]
    op_time = sum(e.self_cpu_time_total for e in ops)
    all_time = sum(e.self_cpu_time_total for e in events)
    top = sorted(ops, key=lambda e: e.self_cpu_time_total, reverse=True)[:3]
    return totals, {
        "top": ", ".join(f"{e.key[6:]} {100 * e.self_cpu_time_total / op_time:.0f}%" for e in top),
        "calls": sum(e.count for e in ops),
        "outside": 100 * (1 - op_time / all_time) if all_time else 0.0,
    }


def data_loading_line(steps: int = 3) -> str:
    """CPU ms per batch of the train loader (in this process), or why it was skipped."""
    root = REPO / "data/parts_tiny"
    if not (root / "manifest.json").is_file():
        return f"data loading: skipped ({root} not built)"
    from data_modules import ShapeDataModule

    module = ShapeDataModule(root=str(root), batch_size=BATCH, num_workers=0, observability="full",
                             points={"train": {"surface": 2048, "sdf": 4096}})
    module.setup("fit")
    batches, start = 0, time.process_time()
    while batches < steps:  # whole epochs: a small split may hold fewer batches than ``steps``
        batches += sum(1 for _ in module.train_dataloader())
    ms = 1000 * (time.process_time() - start) / batches
    return (f"data loading: {ms:.0f} ms CPU per batch of {BATCH} (ShapeDataModule train loader, "
            f"{root.name} records, 2048 surface + 4096 SDF points, in-process)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--paths", nargs="+", default=["fast"], choices=["reference", "fast", "bf16"])
    parser.add_argument("--models", nargs="+", default=MODELS, choices=MODELS)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--steps", type=int, default=2)
    parser.add_argument("--no-data", action="store_true", help="skip the data-loading line")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"{torch.get_num_threads()} threads, OMP_WAIT_POLICY={os.environ.get('OMP_WAIT_POLICY', '(unset)')}, "
          f"GOMP_SPINCOUNT={os.environ.get('GOMP_SPINCOUNT', '(unset)')}, "
          f"batch {BATCH}, medium configs")
    print("| model | path | CPU s/step | forward | backward | optimizer | top operators (self CPU) | op calls "
          "| outside ops |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.models:
        model, batch = build(name)
        for p in args.paths:
            with path(p):
                times, ops = phases(model, batch, args.steps)
            total = sum(times.values())
            shares = " | ".join(f"{100 * t / total:.0f}%" for t in times.values())
            print(f"| {name} | {p} | {total:.3f} | {shares} | {ops['top']} | {ops['calls']} | {ops['outside']:.0f}% |",
                  flush=True)
    if not args.no_data:
        print(data_loading_line())


if __name__ == "__main__":
    main()
