"""``radar2shape sweep``: the grid schema, one folder per run, and resuming after a kill (toy sphere config)."""

import json
import os
from pathlib import Path

import lightning as L
import pytest
import torch
import yaml

from radar2shape import cli, sweep
from radar2shape.errors import UserInputError
from radar2shape.reporting import write_report

REPO = Path(__file__).resolve().parents[1]

TOY = "conf/experiment/toy_sphere.yaml"
TINY = {
    "trainer.max_epochs": 1,
    "trainer.enable_progress_bar": False,
    "trainer.enable_model_summary": False,
    "data.init_args.num_train": 16,
    "data.init_args.num_val": 8,
}


def run_sweep(argv):
    """``radar2shape sweep ARGV`` (through run_tool, so tests may patch cli.main for the runs)."""
    return cli.run_tool("sweep", [str(a) for a in argv])


def write_grid(tmp_path, **spec):
    path = tmp_path / "grid.yaml"
    path.write_text(yaml.safe_dump({"out_dir": str(tmp_path / "runs"), **spec}, sort_keys=False))
    return path


def toy_grid(tmp_path):
    matrix = {"hidden": {"h8": {"overrides": {"model.init_args.mlp_hidden": 8}}, "h16": {"overrides": {"model.init_args.mlp_hidden": 16}}}}
    return write_grid(tmp_path, configs=[TOY], overrides=TINY, matrix=matrix, threads=1)


def test_matrix_expands_in_order_and_later_axes_win(tmp_path):
    matrix = {
        "model": {"a": {"configs": ["m_a.yaml"], "overrides": {"x": 1}}, "b": {"overrides": {"x": 2}}},
        "noise": {"low": {"overrides": {"x": 3, "n": -80}}, "high": {"overrides": {"n": -40}}},
    }
    grid = sweep.load_grid(write_grid(tmp_path, configs=["base.yaml"], overrides={"e": 1}, matrix=matrix,
                                      runs=[{"name": "extra", "overrides": {"e": 2}}]))
    assert [r.name for r in grid.runs] == ["a-low", "a-high", "b-low", "b-high", "extra"]
    first = grid.runs[0]
    assert first.configs == ["base.yaml", "m_a.yaml"]
    assert first.overrides == {"e": 1, "x": 3, "n": -80}
    assert grid.runs[-1].overrides == {"e": 2}
    args = first.args(tmp_path / "r")
    assert args[:2] == ["--config=base.yaml", "--config=m_a.yaml"]
    assert "--n=-80" in args and args[-1] == f"--trainer.default_root_dir={tmp_path / 'r'}"


@pytest.mark.parametrize(
    "spec, message",
    [
        ({"runs": [{"name": "a"}, {"name": "a"}]}, "duplicate"),
        ({"runs": [{"name": "a/b"}]}, "run name"),
        ({"runs": [{"configs": []}]}, "needs a 'name'"),
        ({"runs": [{"name": "a"}], "bogus": 1}, "key 'bogus': unknown key"),
        ({"runs": [{"name": "a", "overrides": {}, "bogus": 1}]}, r"runs\[0\]: key 'bogus': unknown key"),
        ({"runs": [{"name": "a", "configs": "x.yaml"}]}, r"runs\[0\]: key 'configs'"),
        ({"runs": [{"name": "a"}], "threads": "two"}, "key 'threads'"),
        ({"runs": [{"name": "a"}], "test": "maybe"}, "key 'test'"),
        ({"matrix": {"m": {}}}, "matrix.m: expected a non-empty mapping"),
        ({}, "no runs"),
    ],
)
def test_bad_grids_raise_clear_errors(tmp_path, spec, message):
    with pytest.raises(UserInputError, match=message):
        sweep.load_grid(write_grid(tmp_path, **spec))


def test_missing_grid_file_exits_2(tmp_path, capsys):
    assert run_sweep([str(tmp_path / "nope.yaml")]) == 2
    assert "grid file not found" in capsys.readouterr().err
    assert run_sweep(["no_such_grid"]) == 2
    assert "grid file not found: conf/grid/no_such_grid.yaml" in capsys.readouterr().err


def test_sweep_help_and_list(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["sweep", "--help"])
    assert exit_info.value.code == 0 and "--keep-going" in capsys.readouterr().out
    assert run_sweep([chained_grid(tmp_path), "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in lines] == ["a [todo]", "ref [todo]", "b [todo]"]
    assert lines[2].startswith("b [todo]: test --config=conf/experiment/toy_sphere.yaml") and "--ckpt_path=" in lines[2]


@pytest.mark.parametrize("path", sorted((REPO / "conf" / "grid").glob("*.yaml")), ids=lambda p: p.stem)
def test_every_grid_file_loads(path, monkeypatch):
    """Each grid validates, names a report layout, and its config files exist."""
    monkeypatch.chdir(REPO)
    grid = sweep.load_grid(path.stem)
    assert grid.path == Path("conf/grid") / path.name and grid.runs and grid.report is not None
    for run in grid.runs:
        for config in run.configs + [v for v in run.overrides.values() if str(v).endswith(".yaml")]:
            assert (REPO / config).is_file(), (run.name, config)
    for command in grid.prepare:
        assert command[0] in cli.TOOL_COMMANDS and (REPO / command[command.index("--config") + 1]).is_file()


def test_killed_sweep_resumes_and_skips_finished_runs(tmp_path, monkeypatch):
    grid_path = toy_grid(tmp_path)
    real_main = cli.main
    calls = []

    def killed_during_second_fit(args):
        calls.append((args[0], args[-1]))
        code = real_main(args)
        if len(calls) == 3:  # fit h8, test h8, fit h16 -> "killed" before h16's test
            raise KeyboardInterrupt
        return code

    monkeypatch.setattr(cli, "main", killed_during_second_fit)
    with pytest.raises(KeyboardInterrupt):
        run_sweep([str(grid_path)])
    runs = tmp_path / "runs"
    assert (runs / "h8" / "done").is_file() and not (runs / "h16" / "done").exists()
    h8_done = (runs / "h8" / "done").stat().st_mtime_ns

    calls.clear()
    monkeypatch.setattr(cli, "main", lambda args: calls.append(args[0]) or real_main(args))
    h8_checkpoint = next((runs / "h8" / "fit").rglob("*.ckpt"))
    h8_checkpoint_mtime = h8_checkpoint.stat().st_mtime_ns
    assert run_sweep([str(grid_path)]) == 0
    assert calls == ["fit", "test"]  # only the unfinished run, from scratch
    assert (runs / "h8" / "done").stat().st_mtime_ns == h8_done
    assert h8_checkpoint.stat().st_mtime_ns == h8_checkpoint_mtime  # h8 was not refitted
    record = json.loads((runs / "h16" / "done").read_text())
    assert record["name"] == "h16" and record["wall_seconds"] > 0
    assert (runs / "h16" / record["checkpoint"]).is_file()
    assert "radius_l1" in json.loads((runs / "h16" / "metrics.json").read_text())
    assert len(list((runs / "h16" / "fit").glob("version_*"))) == 1  # partial logs were cleared

    calls.clear()
    threads = torch.get_num_threads()
    assert run_sweep([str(grid_path)]) == 0 and calls == []
    assert torch.get_num_threads() == threads  # the grid's `threads: 1` applied only while it ran


def shipped_checkpoint_callback(name: str = "shape_metrics") -> dict:
    """The ModelCheckpoint entry of conf/callbacks/NAME.yaml, the one every grid run uses."""
    callbacks = yaml.safe_load((REPO / "conf" / "callbacks" / f"{name}.yaml").read_text())["trainer"]["callbacks"]
    return next(c for c in callbacks if c["class_path"].endswith("ModelCheckpoint"))


SAVE_LAST = [shipped_checkpoint_callback()]


def chained_grid(tmp_path):
    """``a`` fits; ``ref`` only tests a fresh model; ``b`` only tests ``a``'s checkpoint (as a zero-shot row does)."""
    last = str(tmp_path / "runs" / "a" / "fit" / "version_0" / "checkpoints" / "last.ckpt")
    runs = [
        {"name": "a", "overrides": {"trainer.callbacks": SAVE_LAST}},
        {"name": "ref", "command": "test"},
        {"name": "b", "command": "test", "overrides": {"ckpt_path": last}},
    ]
    return write_grid(tmp_path, configs=[TOY], overrides=TINY, runs=runs, threads=1)


def test_test_only_runs_and_dependencies_by_path(tmp_path, monkeypatch):
    grid_path = chained_grid(tmp_path)
    grid = sweep.load_grid(grid_path)
    assert [(r.name, r.command, grid.needs(r)) for r in grid.runs] == [("a", "fit", []), ("ref", "test", []), ("b", "test", ["a"])]
    real_main = cli.main
    calls = []
    monkeypatch.setattr(cli, "main", lambda args: calls.append((args[0], args[-1].split("=")[0])) or real_main(args))
    assert run_sweep([str(grid_path)]) == 0
    # a: fit + test on its checkpoint; ref and b: test only, b with its own ckpt_path and no other
    assert calls == [("fit", "--trainer.default_root_dir"), ("test", "--ckpt_path"),
                     ("test", "--trainer.default_root_dir"), ("test", "--trainer.default_root_dir")]
    runs = tmp_path / "runs"
    for name in ("ref", "b"):
        record = json.loads((runs / name / "done").read_text())
        assert record["command"] == "test" and "fit_seconds" not in record and record["wall_seconds"] == record["test_seconds"] > 0
        assert not (runs / name / "fit").exists() and "radius_l1" in json.loads((runs / name / "metrics.json").read_text())
    metrics = {n: json.loads((runs / n / "metrics.json").read_text())["radius_l1"] for n in ("a", "ref", "b")}
    assert metrics["b"] == metrics["a"] != metrics["ref"]  # b scored a's trained weights, not a fresh model

    # a redone dependency makes its dependants stale; independent runs stay done
    later = (runs / "b" / "done").stat().st_mtime + 1.0  # as if `a` was redone after b finished
    os.utime(runs / "a" / "done", (later, later))
    calls.clear()
    assert run_sweep([str(grid_path)]) == 0
    assert [c[0] for c in calls] == ["test"]  # b only

    # a run whose arguments changed in the grid is redone (and so are its dependants)
    spec = yaml.safe_load(grid_path.read_text())
    spec["runs"][0]["overrides"]["model.init_args.mlp_hidden"] = 8
    grid_path.write_text(yaml.safe_dump(spec, sort_keys=False))
    calls.clear()
    assert run_sweep([str(grid_path)]) == 0
    assert [c[0] for c in calls] == ["fit", "test", "test"]  # a (changed), then b (a finished after it)


def test_dependencies_must_come_first_and_be_done(tmp_path, capsys):
    last = str(tmp_path / "runs" / "a" / "fit" / "version_0" / "checkpoints" / "last.ckpt")
    with pytest.raises(UserInputError, match="'b' uses a path under .*a, which is not a run listed before it"):
        sweep.load_grid(write_grid(tmp_path, runs=[{"name": "b", "overrides": {"ckpt_path": last}}, {"name": "a"}]))
    with pytest.raises(UserInputError, match="command must be one of"):
        sweep.load_grid(write_grid(tmp_path, runs=[{"name": "a", "command": "predict"}]))
    with pytest.raises(UserInputError, match="matrix.m.x: key 'command': unknown key"):  # command is per run, not per axis value
        sweep.load_grid(write_grid(tmp_path, matrix={"m": {"x": {"command": "test"}}}))
    assert run_sweep([str(chained_grid(tmp_path)), "--only", "b"]) == 1  # a not done: one line, no traceback
    err = capsys.readouterr().err
    assert "b: FAILED: needs ['a'], not done" in err and "Traceback" not in err
    assert not (tmp_path / "runs" / "b").exists()


def test_prepare_threads_and_report_keys(tmp_path):
    grid = sweep.load_grid(write_grid(tmp_path, runs=[{"name": "a"}], threads=1, report="rollsym",
                                      prepare=[["build-data", "--config", "c.yaml", "--num", 3]]))
    assert grid.threads == 1 and grid.report == "rollsym"
    assert grid.prepare == [["build-data", "--config", "c.yaml", "--num", "3"]]
    with pytest.raises(UserInputError, match="key 'report': unknown report layout 'scripts/x.py'"):  # a layout, not a script
        sweep.load_grid(write_grid(tmp_path, runs=[{"name": "a"}], report="scripts/x.py"))
    with pytest.raises(UserInputError, match="prepare"):
        sweep.load_grid(write_grid(tmp_path, runs=[{"name": "a"}], prepare="build-data"))
    with pytest.raises(UserInputError, match="threads"):
        sweep.load_grid(write_grid(tmp_path, runs=[{"name": "a"}], threads=0))
    with pytest.raises(UserInputError, match="key 'jobs': expected a positive integer, got 0"):
        sweep.load_grid(write_grid(tmp_path, runs=[{"name": "a"}], jobs=0))
    assert sweep.load_grid(write_grid(tmp_path, runs=[{"name": "a"}], jobs=2)).jobs == 2


def test_rollsym_table_reads_finished_runs(tmp_path):
    matrix = {axis: {v: {} for v in values} for axis, values in
              {"model": ["unet", "invrt"], "obs": ["full", "partial"], "noise": ["low"]}.items()}
    grid_path = write_grid(tmp_path, matrix=matrix, report="rollsym")
    for name, iou_s in {"unet-full-low": 0.9, "invrt-full-low": 0.7, "invrt-partial-low": 0.5}.items():
        run_dir = tmp_path / "runs" / name
        run_dir.mkdir(parents=True)
        (run_dir / "metrics.json").write_text(json.dumps({"iou_s_mean": iou_s, "iou_s_std": 0.1, "iou_r_mean": 0.5,
                                                          "iou_r_std": 0.2, "match_s_mean": 0.05, "match_s_std": 0.01}))
        (run_dir / "done").write_text(json.dumps({"wall_seconds": 60.0}))
    text = write_report(sweep.load_grid(grid_path), tmp_path / "report").read_text()
    assert "### Low noise (-80 dB)" in text
    assert "| Profile U-Net diffusion (ours) | **0.500 ± 0.200** | **0.900 ± 0.100** | **0.050 ± 0.010** | n/a | n/a | n/a |" in text
    assert "3 of 4 runs finished; summed wall time of the runs 3.0 min" in text
    assert (tmp_path / "report" / "table.csv").read_text().startswith("model,full/iou_r_mean")


@pytest.mark.slow
def test_sigkill_mid_sweep_then_rerun(tmp_path):
    """A real kill (SIGKILL to the process group) once the first run is done; about 30 s."""
    import os
    import signal
    import subprocess
    import sys
    import time

    grid_path = toy_grid(tmp_path)
    done = tmp_path / "runs" / "h8" / "done"
    command = [sys.executable, "-m", "radar2shape.cli", "sweep", str(grid_path)]
    process = subprocess.Popen(command, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 240
        while not done.exists() and process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert done.exists(), "the first run did not finish in time"
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    finished = done.stat().st_mtime_ns
    result = subprocess.run(command, capture_output=True, text=True, timeout=240)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "h8: done, skipped" in result.stdout
    assert done.stat().st_mtime_ns == finished
    assert (tmp_path / "runs" / "h16" / "done").is_file()


@pytest.mark.slow
def test_parallel_jobs_respect_dependencies_and_match_serial(tmp_path):
    """``--jobs 2``: each run in its own process, ``b`` only after ``a`` (it tests a's checkpoint);
    the scores equal a serial sweep's (same seeds, one thread each)."""
    grid_path = chained_grid(tmp_path)
    assert run_sweep([str(grid_path), "--jobs", "2"]) == 0
    runs = tmp_path / "runs"
    parallel = {n: json.loads((runs / n / "metrics.json").read_text())["radius_l1"] for n in ("a", "ref", "b")}
    assert parallel["b"] == parallel["a"] != parallel["ref"]
    assert all((runs / f"{n}.log").is_file() for n in ("a", "ref", "b"))
    # b's test started after a's done marker was written
    assert (runs / "b" / "run.yaml").stat().st_mtime >= (runs / "a" / "done").stat().st_mtime
    # a rerun skips everything; a serial rerun from scratch gives the same numbers
    assert run_sweep([str(grid_path), "--jobs", "2"]) == 0
    (tmp_path / "serial").mkdir()
    serial_path = write_grid(tmp_path / "serial", **{k: v for k, v in yaml.safe_load(grid_path.read_text()).items()
                                                     if k != "out_dir"})
    spec = yaml.safe_load(serial_path.read_text())
    spec["runs"][2]["overrides"]["ckpt_path"] = spec["runs"][2]["overrides"]["ckpt_path"].replace(str(runs), spec["out_dir"])
    serial_path.write_text(yaml.safe_dump(spec, sort_keys=False))
    assert run_sweep([str(serial_path)]) == 0
    serial = {n: json.loads((Path(spec["out_dir"]) / n / "metrics.json").read_text())["radius_l1"] for n in ("a", "ref", "b")}
    assert serial == pytest.approx(parallel, rel=1e-5)


def test_rollsym_report_shows_what_noise_costs_over_seed_means(tmp_path):
    matrix = {axis: {v: {} for v in values} for axis, values in
              {"model": ["unet"], "obs": ["full"], "noise": ["low", "high"], "seed": ["seed0", "seed1"]}.items()}
    grid_path = write_grid(tmp_path, matrix=matrix, report="rollsym")
    for name, iou_s in {"unet-full-low-seed0": 0.80, "unet-full-low-seed1": 0.70,
                        "unet-full-high-seed0": 0.50, "unet-full-high-seed1": 0.60}.items():
        run_dir = tmp_path / "runs" / name
        run_dir.mkdir(parents=True)
        (run_dir / "metrics.json").write_text(json.dumps({"iou_s_mean": iou_s, "iou_s_std": 0.1, "full/frusta1/iou_s_mean": 0.0}))
        (run_dir / "done").write_text(json.dumps({"wall_seconds": 60.0}))
    text = write_report(sweep.load_grid(grid_path), tmp_path / "report").read_text()
    assert "| Profile U-Net diffusion (ours) | 0.750 | 0.550 | +0.200 |" in text  # seed means 0.75 and 0.55
    assert "**0.750 ± 0.100** (seeds ± 0.071)" in text  # std of (0.8, 0.7), ddof 1


class InterruptOnce(L.Callback):
    """Ctrl+C at the start of epoch ``at_epoch``, the first time only (``flag`` remembers): the same
    command then runs through, as a sitting cut short and resumed."""

    def __init__(self, flag: str, at_epoch: int = 1) -> None:
        self.flag, self.at_epoch = Path(flag), at_epoch

    def on_train_epoch_start(self, trainer, pl_module) -> None:
        if trainer.current_epoch == self.at_epoch and not self.flag.exists():
            self.flag.touch()
            raise KeyboardInterrupt


def test_interrupted_fit_resumes_from_its_last_checkpoint(tmp_path, monkeypatch):
    """Epoch 0 finishes and saves last.ckpt, Ctrl+C at epoch 1 (in a child: Lightning exits the
    process); the rerun continues from that checkpoint instead of refitting epoch 0. Validation is
    sparse (every 5 epochs, as the long grid rows): the shipped callback still saves every epoch."""
    import subprocess
    import sys

    assert shipped_checkpoint_callback("profile_metrics") == shipped_checkpoint_callback("shape_metrics")
    interrupt = {"class_path": "tests.test_sweep.InterruptOnce", "init_args": {"flag": str(tmp_path / "interrupted")}}
    overrides = {**TINY, "trainer.max_epochs": 2, "trainer.check_val_every_n_epoch": 5,
                 "trainer.callbacks": [*SAVE_LAST, interrupt]}
    grid_path = write_grid(tmp_path, configs=[TOY], overrides=overrides, runs=[{"name": "a"}], threads=1)
    first = subprocess.run([sys.executable, "-m", "radar2shape.cli", "sweep", str(grid_path)], cwd=REPO,
                           capture_output=True, text=True, timeout=240)
    run_dir = tmp_path / "runs" / "a"
    assert first.returncode != 0 and (tmp_path / "interrupted").exists(), first.stderr[-2000:]
    assert not (run_dir / "done").exists() and not (run_dir / "failed").exists()
    saved = run_dir / "fit" / "version_0" / "checkpoints" / "last.ckpt"
    epoch0 = torch.load(saved, weights_only=False)
    assert epoch0["epoch"] == 0 and epoch0["global_step"] > 0
    assert sweep.resumable_checkpoint(sweep.load_grid(grid_path).runs[0], run_dir) == saved

    real_main, calls = cli.main, []
    monkeypatch.setattr(cli, "main", lambda args: calls.append(list(args)) or real_main(args))
    assert run_sweep([grid_path]) == 0
    assert [c[0] for c in calls] == ["fit", "test"] and calls[0][-1] == f"--ckpt_path={saved}"
    record = json.loads((run_dir / "done").read_text())
    assert record["resumed_from"] == "fit/version_0/checkpoints/last.ckpt"
    final = torch.load(run_dir / record["checkpoint"], weights_only=False)
    assert final["epoch"] == 1 and final["global_step"] == 2 * epoch0["global_step"]  # epoch 1 only was trained
    assert (run_dir / "metrics.json").is_file()


def test_a_changed_command_failed_run_or_cut_checkpoint_starts_over(tmp_path):
    grid_path = write_grid(tmp_path, configs=[TOY], overrides=TINY, runs=[{"name": "a"}])
    run = sweep.load_grid(grid_path).runs[0]
    run_dir = tmp_path / "runs" / "a"
    checkpoints = run_dir / "fit" / "version_0" / "checkpoints"
    checkpoints.mkdir(parents=True)
    torch.save({"state_dict": {}, "hyper_parameters": {}, "epoch": 0, "global_step": 3}, checkpoints / "last.ckpt")
    (run_dir / "run.yaml").write_text(yaml.safe_dump({"name": "a", "fit": run.args(run_dir / "fit")}))
    assert sweep.resumable_checkpoint(run, run_dir) == checkpoints / "last.ckpt"
    (checkpoints / "last.ckpt").write_bytes((checkpoints / "last.ckpt").read_bytes()[:40])  # cut while written
    assert sweep.resumable_checkpoint(run, run_dir) is None
    torch.save({"state_dict": {}, "hyper_parameters": {}, "epoch": 0, "global_step": 3}, checkpoints / "last.ckpt")
    (run_dir / "failed").write_text("Traceback ...")
    assert sweep.resumable_checkpoint(run, run_dir) is None
    (run_dir / "failed").unlink()
    (run_dir / "run.yaml").write_text(yaml.safe_dump({"name": "a", "fit": ["--trainer.max_epochs=9"]}))
    assert sweep.resumable_checkpoint(run, run_dir) is None


def _at(config: dict, dotted: str):
    """The value at a dotted key of a printed config (KeyError when a level is missing)."""
    for part in dotted.split("."):
        config = config[part]
    return config


def _first_run_of_each_override_set(grid) -> list:
    """One run per distinct (command, configs, override keys): the parse is what is tested, not the values."""
    seen, runs = set(), []
    for run in grid.runs:
        key = (run.command, tuple(run.configs), tuple(run.overrides))
        if key not in seen:
            seen.add(key)
            runs.append(run)
    return runs


@pytest.mark.parametrize("path", sorted((REPO / "conf" / "grid").glob("*.yaml")), ids=lambda p: p.stem)
def test_every_grid_override_lands_where_it_says(path, monkeypatch, capsys, tmp_path):
    """Each ``key.path: value`` of a grid reads back at that key of the run's parsed config.

    Two dotted overrides under one dict-typed value (``points.train.surface`` then
    ``points.train.sdf``) do not merge: the second replaces the whole dict, and the first is lost
    without a word. A grid must give such a value as one dict."""
    monkeypatch.chdir(REPO)
    grid = sweep.load_grid(path.stem)
    for run in _first_run_of_each_override_set(grid):
        with pytest.raises(SystemExit) as exit_info:
            cli.main([run.command, *run.args(tmp_path / run.name), "--print_config"])
        assert exit_info.value.code in (0, None), (run.name, capsys.readouterr().err[-500:])
        printed = yaml.safe_load(capsys.readouterr().out)
        for key, value in run.overrides.items():
            if "." not in key:  # a config file or a class name, expanded by the parser
                continue
            assert _at(printed, key) == value, (run.name, key)
