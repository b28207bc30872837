"""``radar2shape report``: a grid's run folders -> Table 1 (Markdown, CSV) and reconstruction figures."""

import csv
import json

import pytest
import trimesh
import yaml

from radar2shape import cli
from radar2shape.commands import report

METRICS = {  # model -> (chamfer, iou, fscore) means
    "radar2shape": (1.0, 0.8, 0.9),
    "tmnet": (5.0, 0.3, 0.4),
}


def finished_run(run_dir, chamfer, iou, fscore, saved=(0, 1)):
    """A run folder as the sweep leaves it, with test reconstructions saved by the metric callback."""
    recon = run_dir / "test" / "version_0" / "reconstructions" / "test" / "epoch_000"
    recon.mkdir(parents=True)
    for index in saved:
        trimesh.creation.icosphere(1, radius=0.2 + 0.1 * index).export(recon / f"sample_{index:06d}.obj")
    metrics = {"chamfer_l2_x1e3_mean": chamfer, "chamfer_l2_x1e3_std": 0.1, "iou_mean": iou, "iou_std": 0.05,
               "fscore_1pct_mean": fscore, "fscore_1pct_std": 0.02}
    (run_dir / "metrics.json").write_text(json.dumps(metrics))
    (run_dir / "done").write_text(json.dumps({"name": run_dir.name, "fit_seconds": 10.0, "test_seconds": 2.0, "wall_seconds": 12.0}))


@pytest.fixture
def grid(tmp_path):
    runs = tmp_path / "runs"
    names = ["radar2shape_stage1"] + [f"{m}-{g}" for m in METRICS for g in ("full", "partial")]
    path = tmp_path / "table1.yaml"
    path.write_text(yaml.safe_dump({"out_dir": str(runs), "runs": [{"name": n} for n in names]}))
    (runs / "radar2shape_stage1").mkdir(parents=True)
    (runs / "radar2shape_stage1" / "done").write_text(json.dumps({"wall_seconds": 30.0, "fit_seconds": 30.0}))
    for model, (c, i, f) in METRICS.items():
        finished_run(runs / f"{model}-full", c, i, f)
    # tmnet-partial is left unfinished: its cells read n/a; radar2shape-partial failed
    (runs / "radar2shape-partial").mkdir()
    (runs / "radar2shape-partial" / "failed").write_text("Traceback ...")
    # a reference scored by hand with `radar2shape test` (no sweep marker): still a table cell
    logged = runs / "nearest-full" / "test" / "version_0"
    logged.mkdir(parents=True)
    (logged / "metrics.csv").write_text("epoch,test/chamfer_l2_x1e3_mean,test/iou_mean\n0,9.0,0.2\n")
    return path


def test_report_writes_table1_layout_csv_and_figure(grid, tmp_path):
    out = tmp_path / "report"
    assert cli.main(["report", "--grid", str(grid), "--out", str(out)]) == 0
    text = (out / "table1.md").read_text()
    header = next(line for line in text.splitlines() if line.startswith("| model"))
    assert header.count("full:") == 3 and header.count("partial (70 % masked):") == 3
    table, runs = text.split("## Runs")
    rows = {line.split("|")[1].strip(): line for line in table.splitlines() if line.startswith("| ")}
    assert "**1.00 ± 0.10**" in rows["Radar2Shape"] and "**0.800 ± 0.050**" in rows["Radar2Shape"]
    assert "5.00 ± 0.10" in rows["TMNet"] and "**5.00" not in rows["TMNet"]
    assert rows["TMNet"].count("n/a") == 3  # partial not run
    assert "radar2shape_stage1" not in table and "| radar2shape_stage1 | done | 30.0 |" in runs  # auxiliary run
    assert "| radar2shape-partial | failed |" in runs and "| tmnet-partial | missing |" in runs
    assert "**54**" in runs  # total wall time: 30 + 12 + 12
    with (out / "table1.csv").open() as handle:
        table = list(csv.DictReader(handle))
    assert [r["model"] for r in table] == ["Radar2Shape", "TMNet", "Nearest neighbour"]
    assert "9.00 | 0.200 | n/a |" in rows["Nearest neighbour"] and "| nearest-full | tested |" in runs
    assert float(table[1]["full/iou_mean"]) == 0.3 and table[1]["partial/iou_mean"] == ""
    assert (out / "table1_full.png").stat().st_size > 0
    assert "![table1_full](table1_full.png)" in text


def test_grid_name_resolves_under_conf_grid():
    assert str(report.grid_path("table1")) == "conf/grid/table1.yaml"
    assert report.split_name("tmnet-partial-posbr") == ("tmnet", "partial-posbr")
    assert report.split_name("radar2shape_stage1") == ("radar2shape_stage1", None)


def test_missing_grid_is_a_one_line_error(tmp_path, capsys):
    assert cli.main(["report", "--grid", str(tmp_path / "nope.yaml")]) == 2
    assert "nope.yaml not found" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["table1", "table1-paper"])
def test_table1_grids_name_cells_and_train_stage1_first(name):
    """Every run is a known Table 1 cell or a Stage-1 run, config files exist, and each Stage-2 run
    loads the last checkpoint of a Stage-1 run that comes before it (runs execute in file order)."""
    from pathlib import Path

    from radar2shape.sweep import load_grid

    repo = Path(__file__).resolve().parents[1]
    grid = load_grid(repo / report.grid_path(name))
    order = [run.name for run in grid.runs]
    for i, run in enumerate(grid.runs):
        model, group = report.split_name(run.name)
        assert model in report.MODEL_TITLES or run.name.endswith("_stage1"), run.name
        assert group is None or group in report.GROUP_TITLES, run.name
        for path in run.configs + [v for v in run.overrides.values() if str(v).endswith(".yaml")]:
            assert (repo / path).is_file(), path
        checkpoint = run.overrides.get("model.init_args.stage1_ckpt")
        if checkpoint:
            stage1 = f"{model}_stage1"
            assert checkpoint == f"{grid.out_dir}/{stage1}/fit/version_0/checkpoints/last.ckpt"
            assert order.index(stage1) < i
