"""scripts/learning_curves.py: validation curves read from hand-written Lightning CSV logs."""

from __future__ import annotations

import importlib.util
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("learning_curves", REPO / "scripts" / "learning_curves.py")
learning_curves = importlib.util.module_from_spec(spec)
spec.loader.exec_module(learning_curves)

# Lightning's CSV logger: step rows (train/loss_step), epoch rows (train/loss_epoch), validation rows.
LOG = """epoch,step,train/loss_epoch,train/loss_step,val/iou_mean
0,19,,0.5,
0,62,0.40,,
1,79,,0.3,
1,125,,,0.25
1,125,0.20,,
2,188,0.10,,
3,251,,,0.55
3,251,0.05,,
"""


def write_run(root: Path, name: str, text: str) -> None:
    folder = root / name / "fit" / "version_0"
    folder.mkdir(parents=True)
    (folder / "metrics.csv").write_text(text)


def test_curve_pairs_each_validation_with_its_epoch_loss(tmp_path):
    write_run(tmp_path, "a", LOG)
    curve = learning_curves.read_curve(tmp_path / "a/fit/version_0/metrics.csv", "val/iou_mean")
    assert [(p["epoch"], p["step"], p["value"], p["loss"]) for p in curve] == [(1, 125, 0.25, 0.20), (3, 251, 0.55, 0.05)]


def test_wall_seconds_of_each_validation_become_a_column(tmp_path):
    timed = LOG.replace("val/iou_mean\n", "val/iou_mean,val/fit_seconds\n").replace(",0.25\n", ",0.25,61.4\n")
    timed = timed.replace(",0.55\n", ",0.55,130.6\n")
    write_run(tmp_path, "a", timed)
    curve = learning_curves.read_curve(tmp_path / "a/fit/version_0/metrics.csv", "val/iou_mean")
    assert [(p["step"], p["seconds"]) for p in curve] == [(125, 61.4), (251, 130.6)]
    text = learning_curves.markdown({"a": curve}, "val/iou_mean")
    assert "| 3 | 251 | 0.5500 | 0.05 | 131 |" in text and "fit seconds" in text
    untimed = [{**p, "seconds": float("nan")} for p in curve]  # logs from before the column: as they were
    assert "fit seconds" not in learning_curves.markdown({"a": untimed}, "val/iou_mean")


def test_grid_report_lists_fitted_runs_only(tmp_path, monkeypatch):
    runs = tmp_path / "runs"
    write_run(runs, "stage1", LOG)
    write_run(runs, "noval", "epoch,step,train/loss_epoch\n0,62,0.4\n")
    grid = tmp_path / "g.yaml"
    grid.write_text(f"out_dir: {runs}\nruns:\n  - {{name: stage1}}\n  - {{name: noval}}\n"
                    "  - {name: ref, command: test}\n  - {name: missing}\n")
    out = tmp_path / "out"
    assert learning_curves.main(["--grid", str(grid), "--out", str(out)]) == 0
    text = (out / "learning_curves.md").read_text()
    assert "| 3 | 251 | 0.5500 | 0.05 |" in text
    assert "## noval" in text and "no `val/iou_mean` logged" in text
    assert "## ref" not in text and "## missing" not in text
    assert (out / "learning_curves.png").stat().st_size > 0


def test_no_logs_is_one_error_line(tmp_path, capsys):
    grid = tmp_path / "g.yaml"
    grid.write_text(f"out_dir: {tmp_path / 'runs'}\nruns:\n  - {{name: a}}\n")
    assert learning_curves.main(["--grid", str(grid), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:")
    assert not (tmp_path / "o").exists()


def test_runs_folder_replaces_the_grids_out_dir(tmp_path, capsys):
    moved = tmp_path / "moved"
    write_run(moved, "a", LOG)
    grid = tmp_path / "g.yaml"
    grid.write_text(f"out_dir: {tmp_path / 'runs'}\nruns:\n  - {{name: a}}\n")
    out = tmp_path / "o"
    assert learning_curves.main(["--grid", str(grid), "--out", str(out), "--runs", str(moved)]) == 0
    assert "| 1 | 125 | 0.2500 | 0.2 |" in (out / "learning_curves.md").read_text()
    assert learning_curves.main(["--grid", str(grid), "--runs", str(tmp_path / "nowhere")]) == 2
    assert capsys.readouterr().err.strip().startswith("error: --runs:")


def test_only_keeps_the_named_runs_and_rejects_unknown_names(tmp_path, capsys):
    runs = tmp_path / "runs"
    write_run(runs, "a", LOG)
    write_run(runs, "b", LOG)
    grid = tmp_path / "g.yaml"
    grid.write_text(f"out_dir: {runs}\nruns:\n  - {{name: a}}\n  - {{name: b}}\n")
    out = tmp_path / "o"
    assert learning_curves.main(["--grid", str(grid), "--out", str(out), "--only", "b"]) == 0
    text = (out / "learning_curves.md").read_text()
    assert "## b" in text and "## a" not in text
    assert learning_curves.main(["--grid", str(grid), "--out", str(out), "--only", "b", "c"]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"error: --only: c: not runs of grid {grid}"


def test_a_resumed_fit_is_one_curve_over_its_sittings(tmp_path):
    runs = tmp_path / "runs"
    write_run(runs, "a", "epoch,step,val/iou_mean\n1,125,0.25\n")
    later = runs / "a" / "fit" / "version_1"
    later.mkdir(parents=True)
    (later / "metrics.csv").write_text("epoch,step,val/iou_mean\n3,251,0.55\n")
    grid = tmp_path / "g.yaml"
    grid.write_text(f"out_dir: {runs}\nruns:\n  - {{name: a}}\n")
    curve = learning_curves.grid_curves(str(grid), "val/iou_mean")["a"]
    assert [(p["step"], p["value"]) for p in curve] == [(125, 0.25), (251, 0.55)]
