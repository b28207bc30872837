"""``radar2shape report``: a grid's run folders -> Table 1 (Markdown, CSV) and reconstruction figures."""

import csv
import json
import re
import shutil
from pathlib import Path

import pytest
import trimesh
import yaml

from radar2shape import cli, reporting, sweep
from radar2shape.reporting import LAYOUTS, write_report

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
    (runs / "tmnet-full" / "note").write_text("carried over from\nan earlier run\n")
    return path


def test_report_writes_table1_layout_csv_and_figure(grid, tmp_path):
    out = tmp_path / "report"
    assert cli.main(["report", "--grid", str(grid), "--out", str(out)]) == 0
    text = (out / "table1.md").read_text()
    header = next(line for line in text.splitlines() if line.startswith("| model"))
    assert header.count("full:") == 3 and header.count("partial:") == 3  # no finished partial run: nothing to say
    table, runs = text.split("## Runs")
    rows = {line.split("|")[1].strip(): line for line in table.split("###")[0].splitlines() if line.startswith("| ")}
    assert "**1.00 ± 0.10**" in rows["Radar2Shape"] and "**0.800 ± 0.050**" in rows["Radar2Shape"]
    assert "5.00 ± 0.10" in rows["TMNet"] and "**5.00" not in rows["TMNet"]
    assert rows["TMNet"].count("n/a") == 3  # partial not run
    assert "radar2shape_stage1" not in table.split("Notes")[0] and "| radar2shape_stage1 | done | fit | 30.0 |" in runs  # auxiliary run
    assert "- `tmnet-full`: carried over from an earlier run" in table  # a run's note, under the table
    assert "| radar2shape-partial | failed |" in runs and "| tmnet-partial | missing |" in runs
    assert "**54**" in runs  # total wall time: 30 + 12 + 12
    with (out / "table1.csv").open() as handle:
        table = list(csv.DictReader(handle))
    assert [r["model"] for r in table] == ["Radar2Shape", "TMNet"]  # the grid's rows only
    main, outside = text.split("Rows tested outside the grid")
    assert "Nearest neighbour" not in main and "| nearest-full | tested |" in runs
    assert "| Nearest neighbour | **9.00** | **0.200** | n/a |" in outside.split("## Runs")[0]
    assert float(table[1]["full/iou_mean"]) == 0.3 and table[1]["partial/iou_mean"] == ""
    assert (out / "table1_full.png").stat().st_size > 0
    assert "![table1_full](table1_full.png)" in text


def test_figures_show_each_row_once_from_the_replicate_that_saved_most():
    from radar2shape.reporting import Cell

    names = ["radar2shape-full-seed0", "radar2shape-full-seed1", "radar2shape-full-seed2", "nearest-full"]
    cells = [Cell(n, Path(n), "done") for n in names]
    saved = {"radar2shape-full-seed0": 4, "radar2shape-full-seed1": 6, "radar2shape-full-seed2": 6, "nearest-full": 4}
    chosen = reporting.one_replicate_per_row(cells, LAYOUTS["table1"], saved)
    assert [c.name for c in chosen] == ["radar2shape-full-seed1", "nearest-full"]


def test_long_row_titles_are_wrapped_to_fit_beside_their_row():
    from radar2shape.reporting.figures import ROW_LABEL_CHARS, row_label

    title = "Radar2Shape, radar encoder started from the parts model's, Stage 2 for 600 epochs at batch 32"
    label = row_label(title)
    lines = label.split("\n")
    assert len(lines) == 4 and max(map(len, lines)) <= ROW_LABEL_CHARS
    assert " ".join(lines) == title  # only the spaces between words become line breaks
    assert row_label("LIST") == "LIST"


def test_table1_lists_first_stages_scored_on_the_test_split(grid, tmp_path):
    stage1 = Path(yaml.safe_load(grid.read_text())["out_dir"]) / "radar2shape_stage1"
    (stage1 / "metrics.json").write_text(json.dumps({
        "chamfer_l2_x1e3_mean": 0.63, "chamfer_l2_x1e3_std": 0.2, "iou_mean": 0.717, "iou_std": 0.16,
        "fscore_1pct_mean": 0.622, "fscore_1pct_std": 0.1, "iou_count": 100, "num_shapes": 100}))
    out = tmp_path / "report"
    assert cli.main(["report", "--grid", str(grid), "--out", str(out)]) == 0
    section = (out / "table1.md").read_text().split("### First stages on the test split")[1].split("###")[0]
    row = next(line for line in section.splitlines() if line.startswith("| radar2shape_stage1"))
    assert "0.63 ± 0.20" in row and "0.717 ± 0.160" in row and "0.622 ± 0.100" in row and "100 of 100" in row


REPO = Path(__file__).resolve().parents[1]


def _cell(layout, name):
    """``(model, group)`` of a Table 1 run name; ``(name, None)`` for an auxiliary run."""
    where = layout.split(name)
    return (where["row"], where["group"]) if where else (name, None)


def test_posbr_runs_are_column_groups_and_test_only_runs_list_their_command(tmp_path):
    runs = tmp_path / "runs"
    names = ["radar2shape-full", "radar2shape-full-sbr", "radar2shape_lora-full-sbr"]
    path = tmp_path / "table1.yaml"
    path.write_text(yaml.safe_dump({"out_dir": str(runs), "runs": [{"name": n} for n in names]}))
    for name, iou in zip(names, (0.5, 0.3, 0.4)):
        finished_run(runs / name, 2.0, iou, 0.1)
    done = json.loads((runs / "radar2shape-full-sbr" / "done").read_text())
    done.update(command="test", wall_seconds=2.0)
    del done["fit_seconds"]
    (runs / "radar2shape-full-sbr" / "done").write_text(json.dumps(done))
    out = tmp_path / "report"
    assert cli.main(["report", "--grid", str(path), "--out", str(out)]) == 0
    text = (out / "table1.md").read_text()
    header = next(line for line in text.splitlines() if line.startswith("| model"))
    assert header.count("| full:") == 3 and header.count("| PO-SBR test, full:") == 3
    rows = {line.split("|")[1].strip(): line for line in text.split("###")[0].splitlines() if line.startswith("| ")}
    assert rows["Radar2Shape"].count("n/a") == 0 and "0.300 ± 0.050" in rows["Radar2Shape"]  # zero-shot cell
    assert rows["Radar2Shape + LoRA (PO-SBR fine-tuned)"].count("n/a") == 3 and "**0.400 ± 0.050**" in rows["Radar2Shape + LoRA (PO-SBR fine-tuned)"]
    assert "| radar2shape-full-sbr | done | test |  | 2.0 | 2.0 |" in text
    assert (out / "table1_full-sbr.png").is_file()


def test_rollsym_grid_writes_its_table2_layout(tmp_path):
    """``radar2shape report --grid rollsym`` writes the Table 2 layout the grid names."""
    matrix = {axis: {v: {} for v in values} for axis, values in
              {"model": ["unet", "invrt"], "obs": ["full", "partial"], "noise": ["low"]}.items()}
    path = tmp_path / "rollsym.yaml"
    path.write_text(yaml.safe_dump({"out_dir": str(tmp_path / "runs"), "matrix": matrix, "report": "rollsym"}, sort_keys=False))
    run_dir = tmp_path / "runs" / "unet-full-low"
    run_dir.mkdir(parents=True)
    (run_dir / "metrics.json").write_text(json.dumps({"iou_s_mean": 0.9, "iou_s_std": 0.1}))
    (run_dir / "done").write_text(json.dumps({"wall_seconds": 120.0}))
    out = tmp_path / "report"
    assert cli.main(["report", "--grid", str(path), "--out", str(out)]) == 0
    text = (out / "table.md").read_text()
    assert "| Profile U-Net diffusion (ours) | n/a | **0.900 ± 0.100** |" in text
    assert "1 of 4 runs finished; summed wall time of the runs 2.0 min" in text
    assert not (out / "rollsym.md").exists()  # not the Table 1 layout
    assert sweep.load_grid(REPO / "conf" / "grid" / "rollsym.yaml").report == "rollsym"
    assert sweep.load_grid(REPO / "conf" / "grid" / "table1.yaml").report == "table1"
    # --layout overrides the grid's: the same runs as a Table 1 layout
    assert cli.main(["report", "--grid", str(path), "--out", str(out), "--layout", "table1"]) == 0
    assert "| unet |" in (out / "rollsym.md").read_text()


def test_unknown_report_layout_is_a_one_line_error(tmp_path, capsys):
    path = tmp_path / "g.yaml"
    path.write_text(yaml.safe_dump({"out_dir": str(tmp_path / "runs"), "runs": [{"name": "a"}], "report": "nope/table.py"}))
    assert cli.main(["report", "--grid", str(path)]) == 2
    assert "unknown report layout 'nope/table.py'" in capsys.readouterr().err


def test_grid_name_resolves_under_conf_grid(monkeypatch):
    monkeypatch.chdir(REPO)
    assert str(sweep.grid_path("table1")) == "conf/grid/table1.yaml"
    table1 = LAYOUTS["table1"]
    assert table1.split("tmnet-partial-posbr") == {"row": "tmnet", "group": "partial-posbr"}
    assert table1.split("radar2shape_stage1") is None
    assert LAYOUTS["rollsym"].split("unet-full-low") == {"row": "unet", "group": "full", "section": "low"}


def test_missing_grid_is_a_one_line_error(tmp_path, capsys):
    assert cli.main(["report", "--grid", str(tmp_path / "nope.yaml")]) == 2
    assert "nope.yaml (give a name under conf/grid/" in capsys.readouterr().err


def test_demo_layout_leads_with_the_shipped_model(tmp_path, monkeypatch):
    """The demo grid's runs -> README.md that explains itself, then the shipped model on unseen shapes,
    then one table per observability of the platform check, CSVs; no file it cites is missing."""
    monkeypatch.chdir(REPO)
    grid = sweep.load_grid("demo")
    assert [r.name for r in grid.runs if r.command == "fit"] == ["stage1", "stage2"] and not grid.test
    assert [r.name for r in grid.runs][:2] == ["shipped-unseen", "nearest-unseen"]
    grid.out_dir = tmp_path / "runs"
    values = {"radar2shape": (14.0, 0.26, 0.08), "nearest": (8.0, 0.43, 0.17), "mean_shape": (79.0, 0.04, 0.02),
              "shipped": (3.0, 0.55, 0.40)}
    for run in grid.runs:
        row = run.name.split("-")[0]
        if row in values:
            finished_run(grid.out_dir / run.name, *values[row], saved=())
    out = tmp_path / "demo"
    text = write_report(grid, out).read_text()
    intro, rest = text.split("## 1. The shipped model on 20 unseen parts shapes", 1)
    assert "**1. The shipped model on shapes it has never seen.**" in intro and "**2. The platform check.**" in intro
    unseen, platform = rest.split("## 2. Platform check: tiny models, full observability")
    full, partial = platform.split("## 2. Platform check: tiny models, partial observability")
    assert "| Radar2Shape, shipped model | **3.00 ± 0.10** | **0.550 ± 0.050** | **0.400 ± 0.020** |" in unseen
    assert "| nearest-neighbour lookup | 8.00 ± 0.10 | 0.430 ± 0.050 | 0.170 ± 0.020 |" in unseen
    assert "| Radar2Shape, tiny (trained here) | 14.00 ± 0.10 | 0.260 ± 0.050 | 0.080 ± 0.020 |" in full
    assert "| nearest-neighbour lookup | **8.00 ± 0.10** | **0.430 ± 0.050** | **0.170 ± 0.020** |" in partial
    assert "| stage1 | missing |" in text
    for cited in re.findall(r"((?:docs|reports|conf)/[\w./-]+\.(?:md|yaml))", text):
        assert (REPO / cited).is_file(), f"the demo report cites {cited}, which does not exist"
    with (out / "table_partial.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [r["model"] for r in rows] == ["Radar2Shape, tiny (trained here)", "nearest-neighbour lookup", "mean-shape"]
    assert float(rows[2]["chamfer_l2_x1e3_mean"]) == 79.0
    assert (out / "table_unseen.csv").is_file()


@pytest.mark.parametrize("name", ["table1", "table1-paper"])
def test_table1_grids_name_cells_and_train_stage1_first(name):
    """Every run is a known Table 1 cell or a Stage-1 run, config files exist, each Stage-2 run
    loads the last checkpoint of a Stage-1 run that comes before it (runs execute in file order),
    every row is in the grid (references and PO-SBR rows included, no manual step), and the
    PO-SBR rows test on an SBR dataset the grid builds, from the PO run of the same observability."""
    from data_modules.config import load_build_config

    repo = REPO
    grid = sweep.load_grid(repo / "conf" / "grid" / f"{name}.yaml")
    layout = LAYOUTS["table1"]
    order = [run.name for run in grid.runs]
    for i, run in enumerate(grid.runs):
        model, group = _cell(layout, run.name)
        assert model in reporting.MODEL_TITLES or run.name.endswith("_stage1"), run.name
        assert group is None or group in reporting.GROUP_TITLES, run.name
        for path in run.configs + [v for v in run.overrides.values() if str(v).endswith(".yaml")]:
            assert (repo / path).is_file(), path
        checkpoint = run.overrides.get("model.init_args.stage1_ckpt")
        if checkpoint:
            stage1 = f"{model}_stage1"
            assert checkpoint == f"{grid.out_dir}/{stage1}/fit/version_0/checkpoints/last.ckpt"
            assert order.index(stage1) < i
    built = {command[command.index("--out") + 1]: command[command.index("--config") + 1] for command in grid.prepare}
    for run in grid.runs:
        model, group = _cell(layout, run.name)
        root = run.overrides.get("data.init_args.root")
        assert root is None or root in built, (run.name, root)
        if group and group.endswith("-sbr"):
            assert load_build_config(repo / built[root]).simulator["method"] == "sbr", run.name
            obs = group.removesuffix("-sbr")
            po_run = run.overrides.get("ckpt_path") or run.overrides.get("model.init_args.base_ckpt")
            assert po_run == f"{grid.out_dir}/radar2shape-{obs}/fit/version_0/checkpoints/last.ckpt", run.name
            assert run.command == ("test" if model == "radar2shape" else "fit"), run.name
            assert run.overrides["data.init_args.observability"] == obs
    cells = {_cell(layout, n) for n in order}
    for model in ("radar2shape", "diffusion_sdf", "tmnet", "list", "nearest", "mean_shape"):
        assert {(model, "full"), (model, "partial")} <= cells, model
    assert {("radar2shape", "full-sbr"), ("radar2shape_lora", "partial-sbr")} <= cells
    assert {r.name: r.command for r in grid.runs if r.name.startswith(("nearest", "mean_shape"))} == {
        f"{m}-{o}": "test" for m in ("nearest", "mean_shape") for o in ("full", "partial")}


def scored_run(run_dir, iou_of_index, n=25, config=None, dependence=0.25):
    """A finished run with per-shape scores (``iou`` = iou_of_index(i)), logged counts and a saved test config."""
    test = run_dir / "test" / "version_0"
    scores_dir = test / "reconstructions" / "test" / "epoch_000"
    scores_dir.mkdir(parents=True)
    with (scores_dir / "scores.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["index", "label", "iou", "radar_dependence_iou"])
        writer.writerows([i, 0, iou_of_index(i), dependence] for i in range(n))
    if config is not None:
        (test / "config.yaml").write_text(yaml.safe_dump({"data": {"class_path": "data_modules.ShapeDataModule",
                                                                   "init_args": config}}))
    ious = [iou_of_index(i) for i in range(n)]
    metrics = {"iou_mean": sum(ious) / n, "iou_std": 0.1, "iou_count": n - 1, "num_shapes": n,
               "radar_dependence_iou_mean": dependence, "radar_dependence_iou_se": 0.01,
               "ceiling_iou_mean": 0.9, "ceiling_iou_std": 0.02,
               "num_eval_points": 30000, "num_pred_points": 30000, "num_occ_points": 100000}
    (run_dir / "metrics.json").write_text(json.dumps(metrics))
    (run_dir / "done").write_text(json.dumps({"wall_seconds": 1.0}))


def test_table1_subset_diagnostics_masks_and_counts(tmp_path):
    from radar2shape.reporting import paper_subset

    runs = tmp_path / "runs"
    names = ["radar2shape-full", "radar2shape-partial", "tmnet-partial"]
    path = tmp_path / "t.yaml"
    path.write_text(yaml.safe_dump({"out_dir": str(runs), "runs": [{"name": n} for n in names]}))
    cells = {"observability": "partial", "mask_rule": "cells", "test_keep": 0.3}
    scored_run(runs / "radar2shape-full", lambda i: i / 100, config={"observability": "full"})
    scored_run(runs / "radar2shape-partial", lambda i: i / 200, config=cells)
    scored_run(runs / "tmnet-partial", lambda i: 0.1, config=cells, dependence=0.0)
    out = tmp_path / "report"
    assert cli.main(["report", "--grid", str(path), "--out", str(out)]) == 0
    text = (out / "t.md").read_text()
    main, subset, diagnostics = text.split("## Runs")[0].split("###")[0], *text.split("###")[1:3]
    header = next(line for line in main.splitlines() if line.startswith("| model"))
    assert header.count("| full:") == 3 and header.count("partial (70 % of cells masked):") == 3
    # the paper's 20 shapes: a fixed subset of the 25 records, re-pooled from the per-shape scores
    chosen = paper_subset(25)
    assert len(set(chosen)) == 20 and chosen == sorted(chosen) and chosen == paper_subset(25) and max(chosen) < 25
    assert paper_subset(12) == list(range(12))
    expected = sum(i / 100 for i in chosen) / 20
    rows = {line.split("|")[1].strip(): line for line in subset.splitlines() if line.startswith("| ")}
    assert f"{expected:.3f} ± " in rows["Radar2Shape"].split("|")[3]
    with (out / "t_20shapes.csv").open() as handle:
        table = {r["model"]: r for r in csv.DictReader(handle)}
    assert float(table["Radar2Shape"]["full/iou_mean"]) == pytest.approx(expected)
    assert float(table["TMNet"]["partial/iou_mean"]) == pytest.approx(0.1)
    # diagnostics: dependence ± standard error, ceiling, "n of N" shapes scored
    rows = {line.split("|")[1].strip(): line for line in diagnostics.splitlines() if line.startswith("| ")}
    assert rows["Radar2Shape"].split("|")[2:5] == [" **0.250 ± 0.010** ", " **0.900 ± 0.020** ", " 24 of 25 "]
    assert "| 0.000 ± 0.010 |" in rows["TMNet"]
    assert "Sampling: CD and F-score on 30,000 ground-truth and 30,000 predicted surface points, IoU on 100,000 occupancy points." in text
    assert sorted(p.name for p in (out / "scores").iterdir()) == sorted(f"{n}.{e}" for n in names for e in ("csv", "json"))
    # runs that masked differently say so; a per-axis mask says "per axis"
    config = dict(cells, mask_rule="per_axis")
    (runs / "tmnet-partial" / "test" / "version_0" / "config.yaml").write_text(yaml.safe_dump(
        {"data": {"class_path": "data_modules.ShapeDataModule", "init_args": config}}))
    assert cli.main(["report", "--grid", str(path), "--out", str(out)]) == 0
    assert "partial (masks differ: 70 % of cells masked, 70 % per axis): IoU" in (out / "t.md").read_text()
    # with the run folders gone, what the report kept beside the scores still says what was masked and sampled
    shutil.rmtree(runs)
    assert "![t_full]" not in (out / "t.md").read_text()  # no reconstructions saved: nothing drawn
    (out / "t_full.png").write_bytes(b"drawn by an earlier report")
    assert cli.main(["report", "--grid", str(path), "--out", str(out)]) == 0
    text = (out / "t.md").read_text()
    assert "![t_full](t_full.png)" in text and "![t_partial]" not in text  # the last drawing of archived runs stands
    assert "partial (masks differ: 70 % of cells masked, 70 % per axis): IoU" in text
    assert "Sampling: CD and F-score on 30,000 ground-truth and 30,000 predicted surface points" in text


def test_masking_from_run_names_without_config():
    from radar2shape.reporting import masking
    from radar2shape.reporting import Cell

    def cell(name):
        return Cell(name, Path("/nonexistent"), "done")

    assert masking(cell("a-partial70cells"), "partial70cells") == "70 % of cells masked"
    assert masking(cell("a-partial-axis"), "partial-axis") == "per axis"
    assert masking(cell("a-full"), "full") is None


def test_rollsym_diagnostics_and_aspect_masks(tmp_path):
    matrix = {"model": {"unet": {}}, "obs": {"full": {}, "partial": {}}, "noise": {"low": {}}}
    path = tmp_path / "rollsym.yaml"
    path.write_text(yaml.safe_dump({"out_dir": str(tmp_path / "runs"), "matrix": matrix, "report": "rollsym"}, sort_keys=False))
    run_dir = tmp_path / "runs" / "unet-partial-low"
    scored_run(run_dir, lambda i: 0.5, n=4, config={"observability": "partial", "test_keep": 0.3})
    (run_dir / "test" / "version_0" / "config.yaml").write_text(yaml.safe_dump(
        {"data": {"class_path": "data_modules.ProfileDataModule", "init_args": {"observability": "partial", "test_keep": 0.3}}}))
    (run_dir / "metrics.json").write_text(json.dumps({"iou_s_mean": 0.5, "iou_s_std": 0.0, "iou_s_count": 4, "num_shapes": 4,
                                                      "radar_dependence_iou_s_mean": 0.2, "radar_dependence_iou_s_se": 0.05}))
    out = tmp_path / "report"
    assert cli.main(["report", "--grid", str(path), "--out", str(out)]) == 0
    text = (out / "table.md").read_text()
    assert "Partial (70 % of aspects masked): IoU-S" in text
    assert "| Profile U-Net diffusion (ours) | n/a | n/a | **0.200 ± 0.050** | 4 of 4 |" in text
    with (out / "diagnostics.csv").open() as handle:
        row, = csv.DictReader(handle)
    assert float(row["partial/radar_dependence_iou_s_se"]) == 0.05 and float(row["partial/iou_s_count"]) == 4


def test_lost_run_folders_are_scored_from_the_scores_the_report_kept(tmp_path, capsys):
    """runs/ is machine-local: a run whose folder is gone comes back from the report's own per-shape
    scores, with the same means, spreads, counts and seed merge; without either the report refuses."""
    import math

    matrix = {"model": {"unet": {}}, "obs": {"full": {}}, "noise": {"low": {}}, "seed": {"seed0": {}, "seed1": {}}}
    path = tmp_path / "rollsym.yaml"
    path.write_text(yaml.safe_dump({"out_dir": str(tmp_path / "runs"), "matrix": matrix, "report": "rollsym"}, sort_keys=False))
    values = {"seed0": [0.2, 0.4, 0.6, float("nan")], "seed1": [0.3, 0.5, 0.7, 0.9]}
    for seed, ious in values.items():
        test = tmp_path / "runs" / f"unet-full-low-{seed}" / "test" / "version_0" / "reconstructions" / "test" / "epoch_000"
        test.mkdir(parents=True)
        with (test / "scores.csv").open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(["index", "label", "iou_s", "radar_dependence_iou_s"])
            writer.writerows([i, 0, "" if math.isnan(v) else v, 0.1 * (i + 1)] for i, v in enumerate(ious))
        finished = [v for v in ious if not math.isnan(v)]
        mean = sum(finished) / len(finished)
        std = math.sqrt(sum((v - mean) ** 2 for v in finished) / len(finished))
        (test.parents[4] / "metrics.json").write_text(json.dumps({
            "iou_s_mean": mean, "iou_s_std": std, "iou_s_count": float(len(finished)), "num_shapes": 4.0,
            "radar_dependence_iou_s_mean": 0.25, "radar_dependence_iou_s_se": math.sqrt(0.05 / 3) / 2}))  # ddof 1 / sqrt(n)
        (test.parents[4] / "done").write_text(json.dumps({"wall_seconds": 2.0}))
    out = tmp_path / "report"
    assert cli.main(["report", "--grid", str(path), "--out", str(out)]) == 0
    before = (out / "table.csv").read_text(), (out / "diagnostics.csv").read_text()
    shutil.rmtree(tmp_path / "runs" / "unet-full-low-seed0")
    assert cli.main(["report", "--grid", str(path), "--out", str(out)]) == 0
    with (out / "table.csv").open() as handle:
        row, = csv.DictReader(handle)
    # seed0 re-pooled from its kept scores: mean 0.4, std sqrt(0.08/3) (ddof 0) over 3 defined shapes
    assert float(row["full/iou_s_mean"]) == pytest.approx((0.4 + 0.6) / 2)
    assert float(row["full/iou_s_std"]) == pytest.approx((math.sqrt(0.08 / 3) + math.sqrt(0.05)) / 2)
    assert float(row["full/iou_s_seeds_std"]) == pytest.approx(math.sqrt(0.02))
    assert ((out / "table.csv").read_text(), (out / "diagnostics.csv").read_text()) == before
    text = (out / "table.md").read_text()
    # the record the report kept beside the scores stands in for the folder's: its wall time survives
    assert "| unet-full-low-seed0 | archived |  |  |  | 2.0 |" in text and "1 more scored from the per-shape scores" in text
    assert "wall time not known" not in text and "summed wall time of the runs 0.1 min" in text
    assert sorted(p.name for p in (out / "scores").iterdir()) == [
        "unet-full-low-seed0.csv", "unet-full-low-seed0.json", "unet-full-low-seed1.csv", "unet-full-low-seed1.json"]
    # a kept score file without its record (an older report) still scores; the wall time is then unknown
    (out / "scores" / "unet-full-low-seed0.json").unlink()
    assert cli.main(["report", "--grid", str(path), "--out", str(out)]) == 0
    assert "wall time not known for 1" in (out / "table.md").read_text()
    # neither a run folder nor kept scores: one clear error line
    shutil.rmtree(tmp_path / "runs")
    assert cli.main(["report", "--grid", str(path), "--out", str(tmp_path / "fresh")]) == 2
    assert "holds no per-shape scores" in capsys.readouterr().err


def test_a_fit_without_a_test_keeps_its_record_once_its_folder_is_gone(grid, tmp_path):
    """A Stage-1 fit has no scores to keep, but the report keeps its record: with its folder gone its
    fit time (30 s) still stands in the runs table and the total, and the record survives a further
    report; a fit the report never saw stays missing."""
    out = tmp_path / "report"
    assert cli.main(["report", "--grid", str(grid), "--out", str(out)]) == 0
    assert json.loads((out / "scores" / "radar2shape_stage1.json").read_text())["record"]["fit_seconds"] == 30.0
    assert not (out / "scores" / "radar2shape_stage1.csv").exists()
    before = (out / "table1.csv").read_text()
    shutil.rmtree(tmp_path / "runs" / "radar2shape_stage1")
    for _ in range(2):
        assert cli.main(["report", "--grid", str(grid), "--out", str(out)]) == 0
        runs = (out / "table1.md").read_text().split("## Runs")[1]
        assert "| radar2shape_stage1 | archived | fit | 30.0 |  | 30.0 |" in runs and "**54**" in runs
    assert (out / "table1.csv").read_text() == before  # a fit is no table row, archived or not
    (out / "scores" / "radar2shape_stage1.json").unlink()
    assert cli.main(["report", "--grid", str(grid), "--out", str(out)]) == 0
    assert "| radar2shape_stage1 | missing |" in (out / "table1.md").read_text()


def test_runs_table_says_when_a_fit_was_resumed(tmp_path):
    from radar2shape.reporting import Cell, runs_table

    resumed = Cell("a-full", tmp_path, "done", {"command": "fit", "fit_seconds": 5.0, "wall_seconds": 6.0,
                                                "resumed_from": "fit/version_0/checkpoints/last.ckpt"})
    whole = Cell("b-full", tmp_path, "done", {"command": "fit", "fit_seconds": 9.0, "wall_seconds": 10.0})
    lines = runs_table([resumed, whole]).splitlines()
    assert lines[2] == "| a-full | done | fit (resumed: fit s of the last sitting) | 5.0 |  | 6.0 |"
    assert lines[3] == "| b-full | done | fit | 9.0 |  | 10.0 |"
