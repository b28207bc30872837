"""scripts/wallclock_check.py: the CPU reference it compares with, and the step it reports as reaching that reference."""

import importlib.util
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("wallclock_check", REPO / "scripts" / "wallclock_check.py")
wallclock_check = importlib.util.module_from_spec(spec)
spec.loader.exec_module(wallclock_check)


def test_cpu_reference_is_the_last_validation_row_of_the_committed_curves():
    # reports/table1-medium/learning_curves.md: Stage 1 ends 0.7135 at step 3779, Stage 2 seed 0 0.5890 at 5039
    assert wallclock_check.cpu_final("radar2shape_stage1") == (3779, 0.7135)
    assert wallclock_check.cpu_final("radar2shape-full-seed0") == (5039, 0.5890)


@pytest.mark.parametrize("rows, expected", [
    ([(4, 314, 0.60, 40.0), (9, 629, 0.72, 80.0)], "Reaches the CPU final at step 629, 80 s after start."),
    ([(4, 314, 0.60, 40.0), (9, 629, 0.7134, 80.0)], "Does not reach the CPU final within the run."),
])
def test_summary_names_the_first_row_at_or_above_the_cpu_final(rows, expected):
    args = type("Args", (), {"minutes": 1.0, "device_name": "test", "loader_workers": 0, "sequential": False, "argv": []})()
    text = wallclock_check.summary("bench", {"stage1-fp32": rows}, {"stage1-fp32": 0}, args)
    assert expected in text and "CPU run's final validation IoU: 0.7135 at step 3779." in text


@pytest.mark.parametrize("name, epochs", [("stage1-bf16", 60), ("stage2-fp32", 80)])
def test_fit_command_is_the_grids_fit_with_the_checks_overrides(name, epochs, tmp_path, capsys):
    from radar2shape.cli import main

    args = type("Args", (), {"out": tmp_path, "minutes": 2.5, "accelerator": "cpu", "data": tmp_path / "data",
                             "loader_workers": 3, "extra": []})()
    command = wallclock_check.fit_command(name, "bf16-mixed" if name.endswith("bf16") else "32", args,
                                          tmp_path / "s1.ckpt")
    assert command[3] == "fit" and "--config=conf/trainer/cpu.yaml" in command
    with pytest.raises(SystemExit):
        main(command[3:] + ["--print_config"])
    printed = yaml.safe_load(capsys.readouterr().out)
    trainer, data = printed["trainer"], printed["data"]["init_args"]
    assert (trainer["max_epochs"], trainer["max_time"], trainer["default_root_dir"]) == (
        epochs, "00:00:02:30", str(tmp_path / "runs" / name))
    assert str(trainer["precision"]) == ("bf16-mixed" if name.endswith("bf16") else "32")
    assert (data["root"], data["num_workers"]) == (str(tmp_path / "data"), 3)
    if name.startswith("stage1"):  # the grid's point budget of Stage 1
        assert data["points"]["train"] == {"surface": 2048, "sdf": 2048}
    else:  # the grid's Stage 2 settings, on the given Stage 1
        assert printed["model"]["init_args"]["stage1_ckpt"] == str(tmp_path / "s1.ckpt")
        assert (trainer["check_val_every_n_epoch"], printed["seed_everything"]) == (10, 0)
