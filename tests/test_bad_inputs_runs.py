"""Bad inputs to fit/validate/test/predict, sweep, report and the CLI itself: each is refused with
exit code 2 and one stderr line naming the file, key or value, and leaves no new file behind
(no run folder, no config.yaml, no report). Nothing trains: every case fails before a run starts."""

from __future__ import annotations

import json
import os
import pickle
from pathlib import Path

import pytest
import yaml

from radar2shape import cli

REPO = Path(__file__).resolve().parents[1]
TOY = str(REPO / "conf" / "experiment" / "toy_sphere.yaml")
PARTS = str(REPO / "conf" / "experiment" / "table1_tiny.yaml")
TMNET = str(REPO / "conf" / "model" / "tmnet_tiny.yaml")


def make_inputs(folder: Path) -> None:
    """The bad files the cases point at, written before the 'no new files' snapshot."""
    folder.mkdir()
    (folder / "text.ckpt").write_text("not a checkpoint\n")
    (folder / "empty.ckpt").write_bytes(b"")
    (folder / "pickle.ckpt").write_bytes(pickle.dumps({"state_dict": os.getcwd}))  # a code reference
    (folder / "folder.ckpt").mkdir()
    (folder / "syntax.yaml").write_text("trainer:\n  max_epochs: [1\n")
    (folder / "list.yaml").write_text("- a\n- b\n")
    (folder / "a_file").write_text("in the way\n")
    (folder / "runs").mkdir()
    (folder / "runs" / "a").mkdir()  # a grid's out_dir with a run folder, so report gets past 'no runs'
    grids = {
        "unknown_key": {"out_dir": "runs", "runs": [{"name": "a"}], "colour": "blue"},
        "bad_type": {"out_dir": "runs", "runs": [{"name": "a"}], "test": "sometimes"},
        "no_runs": {"out_dir": "runs"},
        "duplicate": {"out_dir": "runs", "runs": [{"name": "a"}, {"name": "a"}]},
        "slash_name": {"out_dir": "runs", "runs": [{"name": "a/b"}]},
        "zero_threads": {"out_dir": "runs", "runs": [{"name": "a"}], "threads": 0},
        "bad_command": {"out_dir": "runs", "runs": [{"name": "a", "command": "predict"}]},
        "bad_layout": {"out_dir": str(folder / "runs"), "runs": [{"name": "a"}], "report": "table9"},
        "file_out_dir": {"out_dir": str(folder / "a_file" / "runs"), "runs": [{"name": "a"}]},
        "missing_out_dir": {"out_dir": str(folder / "never_swept"), "runs": [{"name": "a"}]},
        "ok": {"out_dir": str(folder / "runs"), "runs": [{"name": "a"}]},
    }
    for name, spec in grids.items():
        (folder / f"{name}.yaml").write_text(yaml.safe_dump(spec))
    (folder / "grid_syntax.yaml").write_text("out_dir: runs\nruns: [{name: a}\n")


# (case id, argv with IN = the inputs folder and RUNS = a fresh root dir, words the line must hold)
LIGHTNING = [
    ("test-ckpt-missing", ["test", "--config", TOY, "--ckpt_path=IN/none.ckpt"], ["--ckpt_path", "IN/none.ckpt", "not found"]),
    ("test-ckpt-text", ["test", "--config", TOY, "--ckpt_path=IN/text.ckpt"], ["IN/text.ckpt", "a text file"]),
    ("test-ckpt-pickle", ["test", "--config", TOY, "--ckpt_path=IN/pickle.ckpt"], ["IN/pickle.ckpt", "pickle"]),
    ("test-ckpt-empty", ["test", "--config", TOY, "--ckpt_path=IN/empty.ckpt"], ["IN/empty.ckpt", "empty file"]),
    ("test-ckpt-folder", ["test", "--config", TOY, "--ckpt_path=IN/folder.ckpt"], ["IN/folder.ckpt", "folder"]),
    ("validate-ckpt-text", ["validate", "--config", TOY, "--ckpt_path=IN/text.ckpt"], ["radar2shape validate", "IN/text.ckpt"]),
    ("predict-ckpt-pickle", ["predict", "--config", TOY, "--ckpt_path=IN/pickle.ckpt"], ["radar2shape predict", "IN/pickle.ckpt"]),
    ("fit-resume-missing", ["fit", "--config", TOY, "--ckpt_path=IN/none.ckpt"], ["--ckpt_path", "IN/none.ckpt"]),
    ("fit-data-root-missing", ["fit", "--config", PARTS, "--model", TMNET, "--data.init_args.root=IN/no_data"],
     ["dataset folder", "IN/no_data", "not found"]),
    ("test-data-root-missing", ["test", "--config", PARTS, "--model", TMNET, "--data.init_args.root=IN/no_data"],
     ["IN/no_data", "not found"]),
    ("fit-data-root-is-file", ["fit", "--config", PARTS, "--model", TMNET, "--data.init_args.root=IN/a_file"], ["IN/a_file"]),
    ("fit-model-not-reconstruction", ["fit", "--config", TOY, "--model=torch.nn.Linear"], ["torch.nn.Linear"]),
    ("fit-data-not-reconstruction", ["fit", "--config", TOY, "--data=lightning.pytorch.demos.boring_classes.BoringDataModule"],
     ["BoringDataModule"]),
    ("fit-unknown-key", ["fit", "--config", TOY, "--model.init_args.bogus_key=3"], ["bogus_key"]),
    ("fit-wrong-type", ["fit", "--config", TOY, "--trainer.max_epochs=sixty"], ["trainer.max_epochs", "sixty"]),
    ("fit-config-yaml-syntax", ["fit", "--config", "IN/syntax.yaml"], ["IN/syntax.yaml", "YAML syntax error", "line 3"]),
    ("fit-config-missing", ["fit", "--config", "IN/nope.yaml"], ["IN/nope.yaml", "not found"]),
    ("fit-config-equals-missing", ["fit", "--config=IN/nope.yaml"], ["IN/nope.yaml", "not found"]),
    ("fit-config-not-mapping", ["fit", "--config", "IN/list.yaml"], ["radar2shape fit", "config"]),
]
SWEEP = [
    ("sweep-unknown-grid-name", ["sweep", "no_such_grid"], ["conf/grid/no_such_grid.yaml", "not found"]),
    ("sweep-grid-file-missing", ["sweep", "IN/nope.yaml"], ["IN/nope.yaml", "not found"]),
    ("sweep-grid-yaml-syntax", ["sweep", "IN/grid_syntax.yaml"], ["IN/grid_syntax.yaml", "YAML syntax error"]),
    ("sweep-grid-unknown-key", ["sweep", "IN/unknown_key.yaml"], ["IN/unknown_key.yaml", "colour"]),
    ("sweep-grid-bad-type", ["sweep", "IN/bad_type.yaml"], ["IN/bad_type.yaml", "'test'"]),
    ("sweep-grid-no-runs", ["sweep", "IN/no_runs.yaml"], ["IN/no_runs.yaml", "no runs"]),
    ("sweep-duplicate-runs", ["sweep", "IN/duplicate.yaml"], ["IN/duplicate.yaml", "duplicate run names"]),
    ("sweep-unsafe-run-name", ["sweep", "IN/slash_name.yaml"], ["IN/slash_name.yaml", "'a/b'"]),
    ("sweep-zero-threads", ["sweep", "IN/zero_threads.yaml"], ["IN/zero_threads.yaml", "'threads'"]),
    ("sweep-bad-command", ["sweep", "IN/bad_command.yaml"], ["IN/bad_command.yaml", "'predict'"]),
    ("sweep-unknown-layout", ["sweep", "IN/bad_layout.yaml"], ["IN/bad_layout.yaml", "'table9'"]),
    ("sweep-out-dir-under-file", ["sweep", "IN/file_out_dir.yaml"], ["out_dir", "IN/a_file", "is a file"]),
    ("sweep-only-unknown-run", ["sweep", "IN/ok.yaml", "--only", "zz"], ["IN/ok.yaml", "'zz'"]),
    ("sweep-threads-not-int", ["sweep", "IN/ok.yaml", "--threads", "many"], ["radar2shape sweep", "--threads", "'many'"]),
]
REPORT = [
    ("report-unknown-grid-name", ["report", "--grid", "no_such_grid"], ["conf/grid/no_such_grid.yaml"]),
    ("report-grid-never-swept", ["report", "--grid", "IN/missing_out_dir.yaml", "--out", "RUNS/rep"],
     ["IN/never_swept", "no runs to report"]),
    ("report-out-is-file", ["report", "--grid", "IN/ok.yaml", "--out", "IN/a_file"], ["--out", "IN/a_file", "existing file"]),
    ("report-out-under-file", ["report", "--grid", "IN/ok.yaml", "--out", "IN/a_file/rep"], ["--out", "IN/a_file", "is a file"]),
    ("report-unknown-layout-option", ["report", "--grid", "IN/ok.yaml", "--layout", "table9"], ["--layout", "'table9'"]),
    ("report-missing-grid-option", ["report"], ["radar2shape report", "--grid"]),
    ("report-grid-unknown-layout", ["report", "--grid", "IN/bad_layout.yaml", "--out", "RUNS/rep"], ["'table9'"]),
]
CLI = [
    ("cli-unknown-command", ["frobnicate"], ["unknown command 'frobnicate'"]),
    ("cli-debug-unknown-command", ["--debug", "frobnicate"], ["unknown command 'frobnicate'"]),
]
CASES = LIGHTNING + SWEEP + REPORT + CLI


def snapshot(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


@pytest.mark.parametrize("argv, words", [pytest.param(argv, words, id=name) for name, argv, words in CASES])
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(argv, words, tmp_path, monkeypatch, capsys):
    inputs, runs, work = tmp_path / "in", tmp_path / "runs_root", tmp_path / "work"
    make_inputs(inputs)
    work.mkdir()
    monkeypatch.chdir(work)  # relative defaults (runs/default, reports/NAME) would land here
    expand = lambda text: text.replace("IN/", f"{inputs}/").replace("RUNS/", f"{runs}/")  # noqa: E731
    argv = [expand(a) for a in argv]
    if argv[0] in cli.LIGHTNING_COMMANDS:
        argv.append(f"--trainer.default_root_dir={runs}")
    before = snapshot(tmp_path)
    code = cli.main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2, err
    assert len(err.splitlines()) == 1 and err.startswith("error: "), err
    assert "Traceback" not in err
    for word in words:
        assert expand(word) in err, (word, err)
    assert snapshot(tmp_path) == before


def test_case_count():
    """The corpus covers every command of this file at least 5 times, 40+ cases in all."""
    assert len(CASES) >= 40 and len({name for name, _, _ in CASES}) == len(CASES)
    for group in (LIGHTNING, SWEEP, REPORT):
        assert len(group) >= 5


def test_unexpected_error_is_one_line_exit_1_and_traceback_under_debug(monkeypatch, capsys):
    """A bug (not bad input) says so in one line with the --debug hint; --debug shows the traceback."""
    def broken(command, argv):
        raise KeyError("frame")

    monkeypatch.setattr(cli, "dispatch", broken)
    assert cli.main(["report", "--grid", "x"]) == 1
    err = capsys.readouterr().err.strip()
    assert err == ("error: radar2shape report: unexpected KeyError: 'frame' "
                   "(run 'radar2shape --debug report ...' for the traceback)")
    with pytest.raises(KeyError, match="frame"):
        cli.main(["--debug", "report", "--grid", "x"])


def test_debug_shows_the_traceback_of_bad_input_too(tmp_path):
    from radar2shape.errors import UserInputError

    with pytest.raises(UserInputError, match="grid file not found"):
        cli.main(["--debug", "report", "--grid", str(tmp_path / "nope.yaml")])


@pytest.mark.parametrize("error, line", [
    (PermissionError(13, "Permission denied", "/out/r.npz"), "error: radar2shape simulate: /out/r.npz: Permission denied"),
    (IsADirectoryError(21, "Is a directory", "/out"), "error: radar2shape simulate: /out: Is a directory"),
    (FileExistsError(17, "File exists", "/a", None, "/b"), "error: radar2shape simulate: /a -> /b: File exists"),
    (MemoryError(), "error: radar2shape simulate: out of memory (try smaller sizes or batches)"),
    (pickle.UnpicklingError("invalid load key, 'h'."), "error: radar2shape simulate: UnpicklingError: invalid load key, 'h'."),
    (ValueError("wrapped"), None),  # not a known class: exit 1
])
def test_known_error_classes_become_one_line(error, line, monkeypatch, capsys):
    def failing(command, argv):
        raise error

    monkeypatch.setattr(cli, "dispatch", failing)
    code = cli.main(["simulate", "x"])
    err = capsys.readouterr().err.strip()
    assert (code, err) == ((2, line) if line else (1, err)) and len(err.splitlines()) == 1


def test_wrapped_user_error_is_found_in_the_cause_chain():
    """jsonargparse wraps a DataModule's error in a ValueError: the cause chain names the real one."""
    from radar2shape.errors import UserInputError

    inner = UserInputError("data/x: not found")
    try:
        try:
            raise inner
        except UserInputError as err:
            raise ValueError("Does not validate against any of the Union subtypes") from err
    except ValueError as outer:
        assert cli.known_error(outer) is inner
    try:
        try:
            raise FileNotFoundError(2, "No such file", "a")
        except FileNotFoundError:
            raise KeyError("bug while handling")  # only __context__: a bug, not bad input
    except KeyError as outer:
        assert cli.known_error(outer) is None


def test_yaml_error_names_file_line_and_column(tmp_path):
    path = tmp_path / "g.yaml"
    path.write_text("a: [1\n")
    try:
        yaml.safe_load(path.open())
    except yaml.YAMLError as err:
        line = cli.describe_error(err)
    assert line.startswith(f"YAML syntax error: {path}, line 2, column 1: ") and "expected ','" in line


def test_report_is_all_or_nothing(tmp_path, monkeypatch):
    """A layout that fails half-way leaves neither its first file nor the output folder."""
    from radar2shape import reporting, sweep

    grid_file = tmp_path / "g.yaml"
    grid_file.write_text(yaml.safe_dump({"out_dir": str(tmp_path / "runs"), "runs": [{"name": "m-full"}]}))
    (tmp_path / "runs" / "m-full").mkdir(parents=True)
    (tmp_path / "runs" / "m-full" / "done").write_text(json.dumps({"wall_seconds": 1.0}))
    grid = sweep.load_grid(grid_file)

    def half_way(grid, out, layout, shapes, archive):
        (out / "table.csv").write_text("model\n")
        raise OSError(28, "No space left on device", str(out / "table.md"))

    layout = reporting.Layout("half", (), half_way)
    monkeypatch.setattr(reporting.registry, "get_layout", lambda name: layout)
    out = tmp_path / "reports" / "g"
    with pytest.raises(OSError, match="no space left on device") as err:  # the one-line form, naming the report
        reporting.write_report(grid, out)
    assert str(err.value).startswith(f"{out}: ")
    assert not (tmp_path / "reports").exists()
    layout = reporting.Layout("ok", (), lambda grid, out, layout, shapes, archive: (out / "t.md").write_text("x") and out / "t.md")
    assert reporting.write_report(grid, out) == out / "t.md" and sorted(p.name for p in out.iterdir()) == ["t.md"]
