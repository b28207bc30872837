"""scripts/stage1_fit_gap.py: its table from hand-made scores, and one error line for a missing run."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("stage1_fit_gap", REPO / "scripts" / "stage1_fit_gap.py")
stage1_fit_gap = importlib.util.module_from_spec(spec)
spec.loader.exec_module(stage1_fit_gap)


def test_report_rows_are_means_and_population_stds_per_split_and_grid():
    # columns: iou, chamfer x1e3, fscore; a NaN IoU (no mesh) is left out of the IoU mean only
    train = np.array([[0.8, 1.0, 0.5], [0.6, 3.0, 0.7]])
    test = np.array([[0.5, 2.0, 0.4], [np.nan, 4.0, 0.2], [0.7, 6.0, 0.6]])
    text = stage1_fit_gap.report(Path("runs/x"), {"test": {64: test}, "train": {64: train, 128: train}})
    rows = [line for line in text.splitlines() if line.startswith("| t")]
    assert rows == [
        "| test | 3 | 64^3 | 0.600 ± 0.100 | 4.000 ± 1.633 | 0.400 ± 0.163 |",
        "| train | 2 | 64^3 | 0.700 ± 0.100 | 2.000 ± 1.000 | 0.600 ± 0.100 |",
        "| train | 2 | 128^3 | 0.700 ± 0.100 | 2.000 ± 1.000 | 0.600 ± 0.100 |",
    ]


def test_missing_run_is_one_error_line_and_no_output(tmp_path, monkeypatch):
    out = tmp_path / "gap.md"
    monkeypatch.setattr(sys, "argv", ["stage1_fit_gap.py", "--run", str(tmp_path / "nope"), "--out", str(out)])
    with pytest.raises(SystemExit) as exc:
        stage1_fit_gap.main()
    assert str(exc.value).startswith("error: ") and "last.ckpt: not found" in str(exc.value)
    assert "\n" not in str(exc.value) and not out.exists()
