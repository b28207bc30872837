"""Report tables: values, ± formatting, best-in-bold by direction, and CSV round trip."""

import csv
from pathlib import Path

import pytest

from radar2shape.reporting import Column, markdown_table, read_logged_metrics, write_csv

COLUMNS = [Column("chamfer", "CD", higher_is_better=False), Column("iou", "IoU", higher_is_better=True)]
ROWS = [
    ("ours", {"chamfer_mean": 1.5, "chamfer_std": 0.25, "iou_mean": 0.8, "iou_std": 0.1}),
    ("mean-shape", {"chamfer_mean": 4.0, "chamfer_std": 1.0, "iou_mean": 0.85, "iou_std": 0.05}),
]


def test_markdown_table_bolds_best_per_direction():
    table = markdown_table(ROWS, COLUMNS).splitlines()
    assert table[0] == "| model | CD | IoU |"
    assert table[2] == "| ours | **1.500 ± 0.250** | 0.800 ± 0.100 |"
    assert table[3] == "| mean-shape | 4.000 ± 1.000 | **0.850 ± 0.050** |"


def test_missing_metric_shows_na():
    table = markdown_table([("x", {"iou_mean": 0.5})], COLUMNS)
    assert "| x | n/a | **0.500** |" in table


def test_csv_round_trip(tmp_path):
    path = tmp_path / "t.csv"
    write_csv(ROWS, COLUMNS, path)
    rows = list(csv.DictReader(path.open()))
    assert rows[1]["model"] == "mean-shape" and float(rows[1]["iou_std"]) == 0.05
    assert not (tmp_path / "t.csv.tmp").exists()


def test_read_logged_metrics_takes_last_value(tmp_path):
    path = tmp_path / "metrics.csv"
    path.write_text("epoch,test/iou_mean,val/loss\n0,,1.0\n1,0.7,\n2,0.75,\n")
    assert read_logged_metrics(path) == {"iou_mean": 0.75}


def test_layout_maps_run_names_onto_sections_rows_and_groups():
    from pathlib import Path

    from radar2shape.reporting import Cell, Layout

    layout = Layout("t", tuple(COLUMNS), write=None, parts=("row", "group", "section"),
                    row_titles={"a": "Model A"}, group_titles={"full": "Full"})
    cells = [Cell(name, Path(), "done", {}, {"iou_mean": value}) for name, value in
             [("a-full-low", 0.1), ("b-full-low", 0.2), ("a-partial-low", 0.3), ("a-full-high", 0.4), ("stage1", 9.0)]]
    (low, rows, columns), (high, high_rows, high_columns) = layout.tables(cells)
    assert (low, high) == ("low", "high")
    assert [c.header for c in columns] == ["Full: CD", "Full: IoU", "partial: CD", "partial: IoU"]
    assert rows == [("Model A", {"full/iou_mean": 0.1, "partial/iou_mean": 0.3}), ("b", {"full/iou_mean": 0.2})]
    assert high_rows == [("Model A", {"full/iou_mean": 0.4})] and len(high_columns) == 2
    assert layout.split("stage1") is None and layout.split("a-full-sbr-x") == {"row": "a", "group": "full", "section": "sbr-x"}


def test_seed_replicates_merge_into_one_row():
    """``-seed<k>`` runs share a row: mean of the seed means, their std (ddof 1) beside the mean over-shapes std."""
    from radar2shape.reporting import Cell, Column, Layout, markdown_table, merge_seeds

    merged = merge_seeds([{"iou_mean": 0.5, "iou_std": 0.1, "dep_se": 0.03, "iou_count": 20.0},
                          {"iou_mean": 0.7, "iou_std": 0.3, "dep_se": 0.04, "iou_count": 19.0}])
    assert merged["iou_mean"] == pytest.approx(0.6) and merged["iou_seeds_std"] == pytest.approx(0.02 ** 0.5)  # sqrt((0.1^2 + 0.1^2) / 1)
    assert merged["iou_std"] == pytest.approx(0.2) and merged["dep_se"] == pytest.approx(0.025)  # sqrt(.03^2+.04^2)/2
    assert merged["iou_count"] == 19.0 and merged["iou_seeds"] == 2.0
    layout = Layout("t", (Column("iou", "IoU", True),), lambda *a: None, ("row", "group"))
    cells = [Cell(f"m-full-seed{k}", Path(), "done", {}, {"iou_mean": v, "iou_std": 0.1}) for k, v in enumerate((0.4, 0.6, 0.8))]
    cells.append(Cell("n-full", Path(), "done", {}, {"iou_mean": 0.3, "iou_std": 0.05}))
    (section, rows, columns), = layout.tables(cells)
    assert [name for name, _ in rows] == ["m", "n"]
    text = markdown_table(rows, columns)
    assert "| m | **0.600 ± 0.100** (seeds ± 0.200) |" in text and "| n | 0.300 ± 0.050 |" in text
