"""The monocone experiment: its simulated measurements, the cells it hands to the Table-1 report, and its report layout."""

import csv
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from radar2shape import reporting  # (not importing tested_cell by name: pytest would collect it)
from radar2shape.radar.measured import read_csv
from radar2shape.sweep import load_grid

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("monocone_experiment", ROOT / "scripts/monocone_experiment.py")
experiment = importlib.util.module_from_spec(spec)
spec.loader.exec_module(experiment)


def test_measurements_are_scaled_noisy_and_partial(tmp_path):
    args = experiment.parse_args(["--aspect-step-deg", "10", "--num-freq", "5", "--keep", "0.3"])
    config = yaml.safe_load((ROOT / "conf/data/monocone_tiny.yaml").read_text())
    _, _, mesh, profile = next(experiment.targets(config, 1))
    assert mesh.bounds[1, 2] - mesh.bounds[0, 2] == pytest.approx(1.0, abs=1e-6)  # normalised: the length is 1
    assert profile[-1, 1] == pytest.approx(mesh.bounds[1, 2], abs=1e-6)  # profile in the mesh's frame
    files = experiment.measure(mesh, 0, args, tmp_path)
    full, partial = read_csv(files["full"]), read_csv(files["partial"])
    assert full.aspect_only and full.db.shape == (19, 1, 5) and np.isfinite(full.db).all()
    np.testing.assert_allclose(full.freq_hz, np.linspace(7.5e9, 12.5e9, 5) / 0.5)  # measured at 0.5 m
    kept = np.degrees(partial.aspect_rad)
    assert len(kept) == round(0.3 * 19) and np.allclose(np.diff(kept), 10.0)  # one contiguous window
    rows = np.searchsorted(np.degrees(full.aspect_rad), kept)
    np.testing.assert_array_equal(partial.db, full.db[rows])


def test_table1_cells_are_read_by_the_report(tmp_path):
    rows = [{"model": "invrt", "setting": s, "chamfer_l2_x1e3": c, "iou": i, "fscore_1pct": 0.1,
             "iou_s": 0.5, "match_s": 0.1} for s, c, i in [("full", 4.0, 0.6), ("full", 6.0, 0.4), ("partial", 9.0, 0.3)]]
    experiment.write_table1_cells(rows, [("invrt", "a.ckpt", "b.ckpt")], tmp_path)
    full = reporting.tested_cell(tmp_path / "monocone_invrt-full")
    assert full.name == "monocone_invrt-full" and full.state == "tested"
    assert full.metrics["chamfer_l2_x1e3_mean"] == 5.0 and full.metrics["chamfer_l2_x1e3_std"] == 1.0
    assert full.metrics["iou_mean"] == pytest.approx(0.5) and full.metrics["iou_std"] == pytest.approx(0.1)
    assert reporting.tested_cell(tmp_path / "monocone_invrt-partial").metrics["iou_std"] == 0.0


def test_monocone_layout_reads_the_experiment_scores(tmp_path, monkeypatch):
    """``radar2shape report --grid monocone``: mean ± std per model and setting, bold best, the paired
    real-minus-control table and the figure, from the files the experiment leaves."""
    monkeypatch.chdir(ROOT)
    grid = load_grid("monocone")
    assert grid.report == "monocone"
    grid.out_dir = tmp_path / "runs"
    work = grid.out_dir / "experiment"
    work.mkdir(parents=True)
    scores = []
    for model, ious in {"invrt": (0.6, 0.4, 0.5), "invrt_control": (0.5, 0.4, 0.3)}.items():
        for target, iou in enumerate(ious):
            scores.append({"target": target, "seed": target, "model": model, "setting": "full", "observed_cells": 1,
                           "chamfer_l2_x1e3": 4.0 + target, "iou": iou, "fscore_1pct": 0.1, "iou_s": iou, "match_s": "nan"})
    with open(work / "scores.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(scores[0]))
        writer.writeheader()
        writer.writerows(scores)
    info = {"targets": 3, "data_config": "conf/data/monocone_tiny.yaml", "size_m": 0.5, "model_band_ghz": [7.5, 12.5],
            "num_freq": 41, "aspect_step_deg": 1.0, "noise_db": -60.0, "keep": 0.3, "seconds": 60.0,
            "checkpoints": {"invrt": {"full": "a.ckpt", "partial": "b.ckpt"}}}
    (work / "experiment.json").write_text(json.dumps(info))
    sphere = np.random.default_rng(0).normal(size=(500, 3))
    np.savez(work / "surfaces.npz", **{"gt/0": sphere * 0.3, "full/invrt/0": sphere * 0.2})
    out = tmp_path / "report"
    text = reporting.write_report(grid, out).read_text()
    assert "frequencies over 15-25 GHz (= 7.5-12.5 GHz at the models' 1 m)" in text
    assert "| InvRT on monocones | **5.00 ± 0.82** | **0.500 ± 0.082** |" in text
    assert "| InvRT on monocones (control: another target's radar) | **5.00 ± 0.82** | 0.400 ± 0.082 |" in text  # a tie: both bold
    assert "| InvRT | +0.100 ± 0.058 | +0.100 ± 0.058 | n/a | n/a |" in text  # paired differences 0, 0, 0.2
    assert "| InvRT | `a.ckpt` | `b.ckpt` |" in text and (out / "monocone_full.png").is_file()
    with open(out / "monocone.csv", newline="") as handle:
        table = list(csv.DictReader(handle))
    assert table[0]["model"] == "InvRT on monocones" and float(table[0]["full/iou_mean"]) == pytest.approx(0.5)
    assert (out / "scores.csv").is_file()
