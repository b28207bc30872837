"""scripts/monocone_experiment.py: its simulated measurements and the cells it hands to the Table-1 report."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import yaml

from radar2shape.commands import report  # (not importing tested_cell by name: pytest would collect it)
from radar2shape.radar.measured import read_csv

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
    rows = [{"model": "InvRT", "setting": s, "chamfer_l2_x1e3": c, "iou": i, "fscore_1pct": 0.1,
             "iou_s": 0.5, "match_s": 0.1} for s, c, i in [("full", 4.0, 0.6), ("full", 6.0, 0.4), ("partial", 9.0, 0.3)]]
    experiment.write_table1_cells(rows, [("InvRT", "a.ckpt", "b.ckpt")], tmp_path)
    full = report.tested_cell(tmp_path / "monocone_invrt-full")
    assert full.name == "monocone_invrt-full" and full.state == "tested"
    assert full.metrics["chamfer_l2_x1e3_mean"] == 5.0 and full.metrics["chamfer_l2_x1e3_std"] == 1.0
    assert full.metrics["iou_mean"] == pytest.approx(0.5) and full.metrics["iou_std"] == pytest.approx(0.1)
    assert report.tested_cell(tmp_path / "monocone_invrt-partial").metrics["iou_std"] == 0.0
