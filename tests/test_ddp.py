"""Two-process DDP on CPU (gloo) through the CLI: rank 1 relaunches, the evaluator gathers.

The toy model is fitted with ``--trainer.strategy=ddp --trainer.devices=2`` (started as
``python -m radar2shape.cli``) and tested the same way from the ``radar2shape`` console script;
its test metrics must equal a one-process test of the same checkpoint, and every file must be
written once. A hang (a rank relaunched with the wrong command, a collective one rank skips) fails
on the timeout instead of blocking the suite.
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import torch.distributed as dist

from radar2shape.cli import main as cli_main

REPO = Path(__file__).resolve().parents[1]
CONFIGS = ["--config", "conf/trainer/cpu.yaml", "--config", "conf/callbacks/shape_metrics.yaml",
           "--config", "conf/experiment/toy_sphere.yaml"]
DDP = ["--trainer.strategy=ddp", "--trainer.devices=2", "--trainer.accelerator=cpu"]
QUIET = ["--trainer.enable_progress_bar=false", "--trainer.enable_model_summary=false"]
TIMEOUT_S = 180

pytestmark = pytest.mark.skipif(not (dist.is_available() and dist.is_gloo_available()), reason="needs gloo")


def run(command: list[str]) -> None:
    """Run a CLI process group; kill all of it (the relaunched rank too) on timeout."""
    env = {**os.environ, "WANDB_MODE": "disabled"}
    process = subprocess.Popen(command, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True, start_new_session=True)
    try:
        output, _ = process.communicate(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        os.killpg(process.pid, signal.SIGKILL)
        output, _ = process.communicate()
        pytest.fail(f"{' '.join(command[:5])} ... hung for {TIMEOUT_S} s:\n{output[-3000:]}")
    assert process.returncode == 0, output[-3000:]


def logged_test_metrics(run_dir: Path) -> dict[str, float]:
    rows = list(csv.DictReader((run_dir / "metrics.csv").open()))
    return {k: float(v) for row in rows for k, v in row.items() if k.startswith("test/") and v != ""}


def files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.is_file())


def test_two_process_fit_and_test_equal_one_process(tmp_path):
    console_script = Path(sys.executable).with_name("radar2shape")
    if not console_script.is_file():
        pytest.skip("the radar2shape console script is not installed next to this Python")

    fit_dir = tmp_path / "fit"
    run([sys.executable, "-m", "radar2shape.cli", "fit", *CONFIGS, *DDP, *QUIET, "--trainer.max_epochs=2",
         f"--trainer.default_root_dir={fit_dir}"])
    assert files(fit_dir / "version_0" / "checkpoints") == ["epoch=1-step=8.ckpt", "last.ckpt"]  # 64 / (2 x 8) steps
    assert [p.name for p in fit_dir.iterdir()] == ["version_0"]  # one run folder, one logger
    val = fit_dir / "version_0" / "reconstructions" / "val"
    assert len((val / "epoch_001" / "scores.csv").read_text().splitlines()) == 1 + 16  # both ranks' records
    checkpoint = fit_dir / "version_0" / "checkpoints" / "last.ckpt"

    ddp_dir, one_dir = tmp_path / "test_ddp", tmp_path / "test_one"
    run([str(console_script), "test", *CONFIGS, *DDP, *QUIET, f"--ckpt_path={checkpoint}",
         f"--trainer.default_root_dir={ddp_dir}"])
    assert cli_main(["test", *CONFIGS, *QUIET, "--trainer.devices=1", f"--ckpt_path={checkpoint}",
                     f"--trainer.default_root_dir={one_dir}"]) == 0

    ddp, one = logged_test_metrics(ddp_dir / "version_0"), logged_test_metrics(one_dir / "version_0")
    assert {"test/chamfer_l2_x1e3_mean", "test/iou_mean", "test/fscore_1pct_mean", "test/sphere/iou_std"} <= ddp.keys()
    assert ddp.keys() == one.keys()
    for key, value in one.items():
        assert ddp[key] == pytest.approx(value, rel=1e-5, abs=1e-7), key

    # written once, by rank zero, after gathering: the same files as one process, the same rows
    assert files(ddp_dir) == files(one_dir)
    test_files = files(ddp_dir / "version_0" / "reconstructions" / "test" / "epoch_000")
    assert test_files == [f"sample_{i:06d}.{ext}" for i in range(6) for ext in ("obj", "png")] + ["scores.csv"]  # num_saved: 6
    scores = [(ddp_dir if i == 0 else one_dir) / "version_0/reconstructions/test/epoch_000/scores.csv" for i in range(2)]
    ddp_rows, one_rows = (list(csv.DictReader(path.open())) for path in scores)
    assert [int(r["index"]) for r in ddp_rows] == list(range(16))
    for a, b in zip(ddp_rows, one_rows, strict=True):
        assert {k: float(v) for k, v in a.items()} == pytest.approx({k: float(v) for k, v in b.items()}, rel=1e-9)
