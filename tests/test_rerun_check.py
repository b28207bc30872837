"""scripts/rerun_check.py: a finished toy fit rerun from its run.yaml reproduces its own log, a
changed log value is caught, and ``--twice`` compares two reruns instead."""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import yaml

from radar2shape import cli

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("rerun_check", REPO / "scripts" / "rerun_check.py")
rerun_check = importlib.util.module_from_spec(spec)
spec.loader.exec_module(rerun_check)

TINY = {
    "trainer.max_epochs": 2,
    "trainer.log_every_n_steps": 1,
    "trainer.enable_progress_bar": False,
    "trainer.enable_model_summary": False,
    "data.init_args.num_train": 16,
    "data.init_args.num_val": 8,
}


def test_rerun_reproduces_a_fit_and_catches_a_changed_value(tmp_path, monkeypatch):
    grid = tmp_path / "grid.yaml"
    grid.write_text(yaml.safe_dump({"out_dir": str(tmp_path / "runs"), "configs": ["conf/experiment/toy_sphere.yaml"],
                                    "overrides": TINY, "runs": [{"name": "a"}], "threads": 1}))
    assert cli.run_tool("sweep", [str(grid)]) == 0
    run_dir = tmp_path / "runs" / "a"
    log = run_dir / "fit" / "version_0" / "metrics.csv"
    reference = rerun_check.step_values(log, 1)
    assert reference["train/loss_step"], "the toy fit logs a loss every step"

    out = tmp_path / "check.md"
    assert rerun_check.main(["--run", str(run_dir), "--epochs", "1", "--out", str(out)]) == 0
    text = out.read_text()
    assert "bit for bit" in text
    assert f"| `train/loss_step` | {len(reference['train/loss_step'])} | 0 | 0 |" in text

    pristine = tmp_path / "pristine.csv"  # the rerun's log equals it: later checks reuse it, no refit
    pristine.write_bytes(log.read_bytes())
    monkeypatch.setattr(rerun_check, "rerun", lambda args, epochs, threads, root: pristine)
    rows = list(csv.DictReader(log.open()))
    first = next(r for r in rows if r["train/loss_step"])
    first["train/loss_step"] = str(float(first["train/loss_step"]) * 1.01)  # the log now disagrees by 1 %
    with log.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    assert rerun_check.main(["--run", str(run_dir), "--epochs", "1", "--out", str(out)]) == 1
    assert "NOT within rtol 0" in out.read_text()
    assert rerun_check.main(["--run", str(run_dir), "--epochs", "1", "--rtol", "0.02", "--out", str(out)]) == 0
    # --twice compares two reruns with each other: the changed log no longer enters
    assert rerun_check.main(["--run", str(run_dir), "--epochs", "1", "--twice", "--out", str(out)]) == 0
    assert "the second rerun reproduces the first bit for bit" in out.read_text()


def test_a_folder_that_is_not_a_fitted_run_is_one_error_line(tmp_path, capsys):
    assert rerun_check.main(["--run", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "run.yaml" in err[0] and "no recorded fit command" in err[0]
    assert rerun_check.main(["--run", str(tmp_path), "--epochs", "0"]) == 2
    assert "--epochs and --threads must be >= 1" in capsys.readouterr().err


def test_a_rerun_that_fails_is_one_error_line(tmp_path, capsys):
    (tmp_path / "run.yaml").write_text(yaml.safe_dump({"fit": ["--config=conf/missing.yaml"]}))
    log = tmp_path / "fit" / "version_0" / "metrics.csv"
    log.parent.mkdir(parents=True)
    log.write_text("epoch,step,train/loss_step\n0,0,0.5\n")
    assert rerun_check.main(["--run", str(tmp_path), "--epochs", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: the rerun failed (exit 2): error: radar2shape fit: conf/missing.yaml: config file not found"]
