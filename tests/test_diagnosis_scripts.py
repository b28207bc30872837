"""scripts/stage1_fit_gap.py and scripts/paired_scores.py: tables from hand-made scores, one error line on bad input."""

from __future__ import annotations

import importlib.util
import math
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


def test_per_shape_ceilings_carry_index_label_and_pair_with_a_reports_ceiling_columns(tmp_path):
    scores = np.array([[0.5, 2.0, 0.25], [0.75, 4.0, 0.5]])  # iou, chamfer x1e3, fscore per shape
    text = stage1_fit_gap.per_shape_csv(scores, np.array([[7, 2], [3, 0]]))
    assert text.splitlines() == ["index,label,ceiling_iou,ceiling_chamfer_l2_x1e3,ceiling_fscore_1pct",
                                 "7,2,0.5,2.0,0.25", "3,0,0.75,4.0,0.5"]
    mine = tmp_path / "mine.csv"
    mine.write_text(text)
    theirs = tmp_path / "theirs.csv"
    theirs.write_text("index,label,iou,ceiling_iou\n3,0,0.1,0.25\n7,2,0.1,0.5\n")
    a, b = (paired_scores.read_scores(p, ("ceiling_iou",)) for p in (mine, theirs))
    mean, _, n = paired_scores.paired(a, b, "ceiling_iou")
    assert n == 2 and mean == pytest.approx(0.25)  # (0.75 - 0.25 + 0.5 - 0.5) / 2


def test_missing_run_is_one_error_line_and_no_output(tmp_path, monkeypatch):
    out = tmp_path / "gap.md"
    monkeypatch.setattr(sys, "argv", ["stage1_fit_gap.py", "--run", str(tmp_path / "nope"), "--out", str(out)])
    with pytest.raises(SystemExit) as exc:
        stage1_fit_gap.main()
    assert str(exc.value).startswith("error: ") and "last.ckpt: not found" in str(exc.value)
    assert "\n" not in str(exc.value) and not out.exists()
    monkeypatch.setattr(sys, "argv", ["stage1_fit_gap.py", "--run", str(tmp_path), "--ckpt", "best-val-iou.ckpt",
                                      "--out", str(out)])
    with pytest.raises(SystemExit, match="checkpoints/best-val-iou.ckpt: not found"):
        stage1_fit_gap.main()


paired_spec = importlib.util.spec_from_file_location("paired_scores", REPO / "scripts" / "paired_scores.py")
paired_scores = importlib.util.module_from_spec(paired_spec)
paired_spec.loader.exec_module(paired_scores)


def write_scores(path: Path, rows: list[tuple[int, float, float, float]]) -> Path:
    lines = ["index,label,chamfer_l2_x1e3,iou,fscore_1pct"] + [f"{i},0,{cd},{iou},{f}" for i, iou, f, cd in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_paired_scores_pair_by_index_and_drop_undefined(tmp_path):
    # A lists its shapes in another order; shape 3 is only in A; B's IoU of shape 2 is undefined
    a = write_scores(tmp_path / "a.csv", [(2, 0.5, 0.4, 1.0), (0, 0.6, 0.5, 2.0), (1, 0.9, 0.7, 3.0), (3, 0.1, 0.1, 9.0)])
    b = write_scores(tmp_path / "b.csv", [(0, 0.4, 0.5, 4.0), (1, 0.6, 0.3, 3.0), (2, math.nan, 0.2, 2.0)])
    ra, rb = paired_scores.read_scores(a), paired_scores.read_scores(b)
    mean, se, n = paired_scores.paired(ra, rb, "iou")  # differences 0.2, 0.3
    assert n == 2 and mean == pytest.approx(0.25) and se == pytest.approx(0.05)
    mean, se, n = paired_scores.paired(ra, rb, "chamfer_l2_x1e3")  # -2, 0, -1
    assert n == 3 and mean == pytest.approx(-1.0) and se == pytest.approx(1 / math.sqrt(3))
    text = paired_scores.report([("a - b", a, b)])
    assert "| iou | +0.2500 ± 0.0500 | 2 |" in text


def test_paired_scores_name_a_file_without_score_columns(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("index,label,iou\n0,0,0.5\n")
    with pytest.raises(SystemExit) as exc:
        paired_scores.read_scores(bad)
    assert str(exc.value).startswith(f"error: {bad}: expected columns") and "fscore_1pct" in str(exc.value)


def test_paired_scores_pair_the_chosen_profile_columns(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text("index,iou_s,match_s\n0,0.7,0.05\n1,0.9,0.03\n")
    b.write_text("index,iou_s,match_s\n1,0.6,0.04\n0,0.6,0.07\n")
    text = paired_scores.report([("a - b", a, b)], ("iou_s", "match_s"))  # IoU-S +0.1, +0.3; MATCH-S -0.02, -0.01
    assert "| iou_s | +0.2000 ± 0.1000 | 2 |" in text and "| match_s | -0.0150 ± 0.0050 | 2 |" in text
    assert "| iou |" not in text
    with pytest.raises(SystemExit) as exc:  # the default columns are not in a profile score file
        paired_scores.read_scores(a)
    assert str(exc.value).startswith(f"error: {a}: expected columns index, iou")


confidence_spec = importlib.util.spec_from_file_location("confidence_check", REPO / "scripts" / "confidence_check.py")
confidence_check = importlib.util.module_from_spec(confidence_spec)
confidence_spec.loader.exec_module(confidence_check)


def test_confidence_from_scores_is_spearman_over_defined_shapes(tmp_path):
    scores = tmp_path / "run.csv"
    # consistency ranks 1, 2, 3, 4 against IoU ranks 4, 3, 1, 2 (one shape undefined): rho = 1 - 6*18/60 = -0.8
    scores.write_text("index,iou,radar_consistency\n0,0.9,0.1\n1,0.8,0.2\n2,0.1,0.3\n3,0.2,0.4\n4,0.5,nan\n")
    out = tmp_path / "confidence.md"
    assert confidence_check.main(["--scores", str(scores), "--out", str(out)]) == 0
    assert "Spearman(consistency, IoU) = -0.800" in out.read_text() and "over 4 shapes" in out.read_text()
    verified = tmp_path / "verified.csv"  # a verifier's predicted IoU: ranks 3, 2, 1, 4 against IoU 4, 3, 1, 2
    verified.write_text("index,iou,predicted_iou\n0,0.9,0.3\n1,0.8,0.2\n2,0.1,0.1\n3,0.2,0.4\n")
    assert confidence_check.main(["--scores", str(verified), "--out", str(out)]) == 0
    assert "Spearman(predicted IoU, IoU) = +0.400" in out.read_text()  # 1 - 6 * (1 + 1 + 0 + 4) / 60
    plain = tmp_path / "plain.csv"
    plain.write_text("index,iou\n0,0.5\n")
    with pytest.raises(SystemExit) as exc:
        confidence_check.main(["--scores", str(plain), "--out", str(tmp_path / "x.md")])
    assert str(exc.value).startswith(f"error: {plain}: no radar_consistency or predicted_iou column")
    assert not (tmp_path / "x.md").exists()


def test_real_paired_script_names_a_grid_without_scores():
    import subprocess

    result = subprocess.run(["bash", str(REPO / "scripts" / "table1_real_paired.sh"), "no-such-grid"],
                            capture_output=True, text=True)
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.strip().splitlines() == [
        "error: reports/no-such-grid/scores does not exist: run 'radar2shape sweep no-such-grid' first"]
