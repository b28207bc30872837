"""Benchmark: seconds per training step inside a real fit, one setting changed at a time.

    python bench/fit_steps.py [--out reports/throughput/fit_steps.md] [--stages stage1 stage2] [--threads 2]

The synthetic bench (bench/train_throughput.py) times the model's step alone; a fit also loads
records, runs callbacks (the EMA of the weights) and Lightning's loop, and on 2 cores those can cost
as much as the model. Here each stage runs the table1-medium grid's own fit on ``data/parts_medium``
(Stage 2 on ``--stage1-ckpt``, default the Stage 1 inside the shipped model), without validation,
and the wall seconds between optimizer steps ``--skip`` and ``--skip + --steps`` are timed. Each
line adds one change to the line above it, ending at what the table1-medium-fast grid trains with,
so the ratios say what each change buys. The fits run one after another, alone on the machine.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "src"), str(REPO), str(Path(__file__).resolve().parent)]

import radar2shape  # noqa: E402,F401  (before torch: the package's OpenMP settings apply, as in a fit)
import lightning as L  # noqa: E402
from train_throughput import GRID_RUNS  # noqa: E402
FAST = "(table1-medium-fast)"  # marks the line of each stage that the table1-medium-fast grid trains with
LIGHTNING_EMA = "lightning-ema"  # a pseudo-argument: Lightning's own per-tensor EMA callback
# (label, arguments added to the line above); the last line of each is the table1-medium-fast setting
STEPS = {
    "stage1": [
        ("table1-medium as committed (2,048 encoder points, loader process, float32)", []),
        ("loading in the training process", ["--data.init_args.num_workers=0"]),
        ("1,024 encoder points", ["--data.init_args.points.train={surface: 1024, sdf: 2048}"]),
        (f"bfloat16 autocast {FAST}", ["--trainer.precision=bf16-mixed"]),
    ],
    "stage2": [
        ("table1-medium as committed (loader process, Lightning's EMA, float32)", [LIGHTNING_EMA]),
        ("EMA by one foreach lerp", []),
        ("loading in the training process", ["--data.init_args.num_workers=0"]),
        (f"stride-2 stem of the radar ResNet {FAST}", ["--model.init_args.encoder_stem_stride=2"]),
        ("bfloat16 autocast (not adopted)", ["--trainer.precision=bf16-mixed"]),
    ],
    # Exact roll augmentation (the real-target grid's DataModule): a turned sample's latents are not
    # the cached unturned ones, so Stage 1 encodes it unless its (record, turn) was seen before.
    "stage2-roll": [
        ("table1-medium-fast Stage 2 (unturned: latents cached at fit start)",
         ["--data.init_args.num_workers=0", "--model.init_args.encoder_stem_stride=2"]),
        ("roll augmentation: each sample turned, Stage 1 encodes it", ["--data.init_args.roll_augment=true"]),
        ("roll augmentation, (record, turn) latents cached: few repeats in the first steps",
         ["--model.init_args.cache_turned_latents=true"]),
    ],
}


class StepTimer(L.Callback):
    """Wall seconds per optimizer step between two global steps; stops the fit at the second."""

    def __init__(self, start: int, stop: int) -> None:
        self.start, self.stop, self.seconds = start, stop, None

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx) -> None:
        if trainer.global_step == self.start:
            self._began = time.perf_counter()
        elif trainer.global_step == self.stop:
            self.seconds = (time.perf_counter() - self._began) / (self.stop - self.start)
            trainer.should_stop = True


@contextlib.contextmanager
def extra_callbacks(timer: StepTimer, lightning_ema: bool):
    """Every model of the fit also gets ``timer``; with ``lightning_ema`` its EMA is Lightning's own."""
    from lightning.pytorch.callbacks import EMAWeightAveraging

    from radar2shape.models import base

    original = base.ReconstructionModel.configure_callbacks

    def configure_callbacks(model):
        callbacks = original(model)
        if lightning_ema:
            callbacks = [EMAWeightAveraging(decay=float(model.hparams.ema_decay)) if isinstance(c, base.ForeachEMA) else c
                         for c in callbacks]
        return [*callbacks, timer]

    base.ReconstructionModel.configure_callbacks = configure_callbacks
    try:
        yield
    finally:
        base.ReconstructionModel.configure_callbacks = original


def time_fit(stage: str, added: list[str], args: argparse.Namespace, root: Path) -> float:
    """Seconds per step of the grid's fit of ``stage`` with the ``added`` arguments."""
    from radar2shape.cli import main
    from radar2shape.sweep import load_grid

    run = next(r for r in load_grid("table1-medium").runs if r.name == GRID_RUNS[stage.split("-")[0]])
    fit_args = [a for a in run.args(root) if not a.startswith("--model.init_args.stage1_ckpt")]
    fit_args += ["--trainer.limit_val_batches=0", f"--trainer.max_steps={args.skip + args.steps + 1}",
                 f"--data.init_args.root={args.data}"]
    if stage.startswith("stage2"):
        fit_args.append(f"--model.init_args.stage1_ckpt={args.stage1_ckpt}")
    timer = StepTimer(args.skip, args.skip + args.steps)
    with extra_callbacks(timer, LIGHTNING_EMA in added):
        main(["fit", *fit_args, *(a for a in added if a != LIGHTNING_EMA)])
    if timer.seconds is None:
        raise RuntimeError(f"{stage}: the fit stopped before step {args.skip + args.steps}")
    return timer.seconds


def missing_data(script: str, data: Path) -> bool:
    """True (and says so) when the parts_medium records the fits read are not built."""
    if (data / "manifest.json").is_file():
        return False
    print(f"{script}: skipped, no dataset at {data} (radar2shape build-data --config "
          "conf/data/parts_medium.yaml --out data/parts_medium --workers 2)")
    return True


def write_table(lines: list[str], out: Path | None) -> None:
    """Print a markdown table and, with ``out``, write it there too."""
    text = "\n".join(lines) + "\n"
    print(text)
    if out:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stages", nargs="+", default=["stage1", "stage2"], choices=sorted(STEPS))
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--skip", type=int, default=40, help="steps before timing starts (loader and caches warm)")
    parser.add_argument("--steps", type=int, default=100, help="timed steps")
    parser.add_argument("--data", type=Path, default=REPO / "data/parts_medium")
    parser.add_argument("--stage1-ckpt", type=Path, default=REPO / "src/radar2shape/weights/radar2shape_parts_medium.ckpt",
                        help="a Stage-1 checkpoint or a Stage-2 one whose Stage 1 is taken (default: the shipped model)")
    parser.add_argument("--out", type=Path, default=None, help="also write the table here (markdown)")
    parser.add_argument("--fast-only", action="store_true", help="time only the table1-medium-fast line of each stage")
    args = parser.parse_args()
    if missing_data("fit_steps", args.data):
        return
    import torch

    torch.set_num_threads(args.threads)
    lines = [f"Seconds per training step inside the table1-medium fit, {args.threads} threads, steps "
             f"{args.skip}-{args.skip + args.steps}, no validation (`python bench/fit_steps.py`).", "",
             "| stage | change (each line adds to the line above) | s/step | x first line |", "|---|---|---|---|"]
    with tempfile.TemporaryDirectory(prefix="fit_steps_") as tmp:
        for stage in args.stages:
            added, first = [], None
            for i, (label, change) in enumerate(STEPS[stage]):
                added = [*added, *change]
                if args.fast_only and FAST not in label:
                    continue
                seconds = time_fit(stage, added, args, Path(tmp) / f"{stage}-{i}")
                first = first or seconds
                lines.append(f"| {stage} | {label} | {seconds:.3f} | {first / seconds:.2f}x |")
                print(lines[-1], flush=True)
    write_table(lines, args.out)


if __name__ == "__main__":
    main()
