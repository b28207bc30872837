"""SIGTERM (a scheduler's preemption) sent for real to `radar2shape fit`, `sweep` and `build-data`
child processes at a moment shown by a file: one line, exit code 143, nothing partial left, and
the resumed result equal to an uninterrupted one."""

import glob
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

REPO = Path(__file__).resolve().parents[2]
RADAR2SHAPE = str(Path(sys.executable).with_name("radar2shape"))
ENV = {**os.environ, "WANDB_MODE": "disabled", "WANDB_SILENT": "true", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
SIGTERM_EXIT = 143
# One batch per epoch: every SIGTERM lands on a batch that ends an epoch, where resuming is exact.
TOY = [f"--config={REPO / 'conf/trainer/cpu.yaml'}", f"--config={REPO / 'conf/experiment/toy_sphere.yaml'}",
       "--data.init_args.num_train=8", "--data.init_args.num_val=8", "--trainer.enable_progress_bar=false"]
EPOCHS = 16


def start(*args, **popen) -> subprocess.Popen:
    return subprocess.Popen([RADAR2SHAPE, *map(str, args)], cwd=REPO, env=ENV, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **popen)


def wait_for(pattern: str, process: subprocess.Popen, timeout: float = 120) -> None:
    """Poll until a file matching ``pattern`` exists (the moment to send the signal)."""
    deadline = time.time() + timeout
    while not glob.glob(pattern, recursive=True):
        assert process.poll() is None, f"finished before the signal: {process.communicate()}"
        assert time.time() < deadline, f"no {pattern} after {timeout} s"
        time.sleep(0.02)


def terminate(process: subprocess.Popen) -> tuple[int, list[str]]:
    """SIGTERM, then the exit code and the stderr lines that are errors, tracebacks or about the signal."""
    os.kill(process.pid, signal.SIGTERM)
    _, err = process.communicate(timeout=120)
    lines = [line for line in err.splitlines()
             if line.startswith(("error", "Traceback")) or "SIGTERM" in line or "Error" in line]
    return process.returncode, lines


def weights(path) -> dict:
    return torch.load(path, map_location="cpu", weights_only=True)["state_dict"]


def temporaries(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if ".tmp" in p.name]


def test_sigterm_during_fit_saves_last_ckpt_and_resuming_equals_the_uninterrupted_fit(tmp_path):
    reference = start("fit", *TOY, f"--trainer.max_epochs={EPOCHS}", f"--trainer.default_root_dir={tmp_path / 'ref'}")
    cut_args = ["fit", *TOY, f"--trainer.max_epochs={EPOCHS}", f"--trainer.default_root_dir={tmp_path / 'cut'}"]
    cut = start(*cut_args)
    wait_for(str(tmp_path / "cut/version_0/checkpoints/epoch=*.ckpt"), cut)
    code, lines = terminate(cut)
    last = tmp_path / "cut/version_0/checkpoints/last.ckpt"
    resume = " ".join(["radar2shape", *cut_args, f"--ckpt_path={last}"])
    assert code == SIGTERM_EXIT
    assert lines == [f"error: radar2shape fit: stopped by SIGTERM; saved {last}; resume with: {resume}"]
    saved = torch.load(last, map_location="cpu", weights_only=True)
    assert 1 <= saved["global_step"] < EPOCHS  # cut at the signal, not at the end
    assert not temporaries(tmp_path / "cut")

    resumed = start(*cut_args, f"--ckpt_path={last}")
    assert resumed.wait(timeout=300) == 0 and reference.wait(timeout=300) == 0
    final = f"epoch={EPOCHS - 1}-step={EPOCHS}.ckpt"
    expected = weights(tmp_path / "ref/version_0/checkpoints" / final)
    actual = weights(tmp_path / "cut/version_1/checkpoints" / final)
    assert expected.keys() == actual.keys()
    for key in expected:
        assert torch.equal(expected[key], actual[key]), key
    logged = [(tmp_path / run / "metrics.csv").read_text().strip().splitlines()[-1]
              for run in ("ref/version_0", "cut/version_1")]
    assert logged[0] == logged[1]  # the last epoch's validation loss, to the last digit


def toy_grid(tmp_path, jobs: int, names=("a",), epochs: int = EPOCHS) -> Path:
    runs = [{"name": name, "overrides": {"model.init_args.mlp_hidden": 16 + i}} for i, name in enumerate(names)]
    spec = {"out_dir": str(tmp_path / "runs"), "configs": [str(REPO / "conf/experiment/toy_sphere.yaml")],
            "overrides": {"trainer.max_epochs": epochs, "trainer.enable_progress_bar": False,
                          "trainer.enable_model_summary": False, "data.init_args.num_train": 8,
                          "data.init_args.num_val": 8},
            "test": False, "threads": 1, "jobs": jobs, "runs": runs}
    path = tmp_path / "grid.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def test_sigterm_during_a_sweep_leaves_the_run_resumable_and_the_rerun_resumes_it(tmp_path):
    grid = toy_grid(tmp_path, jobs=1)
    runs = tmp_path / "runs"
    sweep = start("sweep", grid)
    wait_for(str(runs / "a/fit/version_0/checkpoints/epoch=*.ckpt"), sweep)
    code, lines = terminate(sweep)
    last = runs / "a/fit/version_0/checkpoints/last.ckpt"
    assert code == SIGTERM_EXIT
    assert lines == [f"error: radar2shape sweep: stopped by SIGTERM during run a (saved {last}); "
                     f"rerun the same command to resume: radar2shape sweep {grid}"]
    assert last.is_file() and not (runs / "a/failed").exists() and not (runs / "a/done").exists()
    assert not (runs / ".sweep.lock").exists() and not temporaries(runs)

    again = start("sweep", grid)
    out, err = again.communicate(timeout=300)
    assert again.returncode == 0, err
    assert f"[sweep] a: resuming from {last}" in out
    record = yaml.safe_load((runs / "a/done").read_text())
    assert record["resumed_from"] == "fit/version_0/checkpoints/last.ckpt"
    # the result is the resumed fit's final checkpoint, not the last.ckpt the signal left
    assert record["checkpoint"] == f"fit/version_1/checkpoints/epoch={EPOCHS - 1}-step={EPOCHS}.ckpt"


@pytest.mark.slow
def test_sigterm_to_a_parallel_sweep_reaches_every_running_run(tmp_path):
    grid = toy_grid(tmp_path, jobs=2, names=("a", "b"), epochs=500)  # neither ends before the signal
    runs = tmp_path / "runs"
    sweep = start("sweep", grid)
    for name in ("a", "b"):
        wait_for(str(runs / name / "fit/version_0/checkpoints/epoch=*.ckpt"), sweep)
    code, lines = terminate(sweep)
    assert code == SIGTERM_EXIT
    assert lines == [f"error: radar2shape sweep: stopped by SIGTERM during runs a, b; "
                     f"rerun the same command to resume: radar2shape sweep {grid}"]
    for name in ("a", "b"):
        last = torch.load(runs / name / "fit/version_0/checkpoints/last.ckpt", map_location="cpu", weights_only=True)
        assert last["global_step"] < 500
        assert not (runs / name / "failed").exists() and not (runs / name / "done").exists()
    assert not temporaries(runs)


def record_arrays(root: Path) -> dict:
    out = {}
    for path in sorted((root / "records").glob("*/*.npz")):
        with np.load(path, allow_pickle=False) as data:
            out[str(path.relative_to(root))] = {key: (data[key].dtype.str, data[key].shape, data[key].tobytes())
                                                for key in data.files}
    return out


def test_sigterm_during_build_data_keeps_finished_records_and_the_rerun_is_byte_equal(tmp_path):
    config, num = REPO / "conf/data/parts_tiny.yaml", 20
    args = ["build-data", "--config", config, "--out", tmp_path / "cut", "--num", num, "--quiet"]
    reference = start("build-data", "--config", config, "--out", tmp_path / "ref", "--num", num, "--quiet")
    cut = start(*args)
    wait_for(str(tmp_path / "cut/records/*/*.npz"), cut)
    code, lines = terminate(cut)
    done = len(list((tmp_path / "cut/records").glob("*/*.npz")))
    assert code == SIGTERM_EXIT and 1 <= done < num
    assert lines == [f"error: radar2shape build-data: stopped by SIGTERM with {done} of {num} records of shard 0/1 "
                     f"done; rerun the same command to continue: radar2shape build-data --config {config} "
                     f"--out {tmp_path / 'cut'} --num {num} --quiet"]
    assert not temporaries(tmp_path / "cut") and not (tmp_path / "cut/manifest.json").exists()
    assert not (tmp_path / "cut/.build-data.lock").exists()

    again = start(*args)
    out, err = again.communicate(timeout=300)
    assert again.returncode == 0, err
    assert f"{done} already done of {num}" in out
    assert reference.wait(timeout=300) == 0
    expected, actual = record_arrays(tmp_path / "ref"), record_arrays(tmp_path / "cut")
    assert len(expected) == num and expected.keys() == actual.keys()
    for name in expected:
        assert expected[name] == actual[name], name
