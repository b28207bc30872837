"""scripts/near_duplicates.py on a tiny dataset with a planted copy of a training shape.

Cubes of half-side 0.375 and 0.4375 hold 24 and 28 of the 32 grid centres per axis
((k - 15.5) / 32, faces half a cell from the nearest centre), so their IoU is (24/28)^3 exactly.
"""

import csv
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from data_modules.manifest import FORMAT
from data_modules.records import record_path, write_record

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("near_duplicates", ROOT / "scripts" / "near_duplicates.py")
near = importlib.util.module_from_spec(spec)
spec.loader.exec_module(near)

SPHERE = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
TRAIN = [trimesh.creation.box(extents=[0.875] * 3), SPHERE, trimesh.creation.cylinder(radius=0.1, height=0.9)]
TEST = [SPHERE.copy(), trimesh.creation.box(extents=[0.75] * 3)]  # a planted copy; a smaller cube


def write_dataset(root: Path, manifest: bool = True) -> None:
    splits = {"train": TRAIN, "test": TEST}
    for split, meshes in splits.items():
        for i, mesh in enumerate(meshes):
            path = record_path(root, split, f"{i:06d}")
            path.parent.mkdir(parents=True, exist_ok=True)
            write_record(path, {"vertices": mesh.vertices.astype(np.float32), "faces": mesh.faces.astype(np.int32)})
    if manifest:
        ids = {split: [f"{i:06d}" for i in range(len(m))] for split, m in splits.items()}
        (root / "manifest.json").write_text(json.dumps({"format": FORMAT, "splits": ids}))


def test_planted_duplicate_is_found_with_iou_one(tmp_path, capsys):
    write_dataset(tmp_path / "data")
    out = tmp_path / "report"
    assert near.main([str(tmp_path / "data"), "--out", str(out)]) == 0
    with (out / "near_duplicates_test.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["record_id"], r["nearest_train_id"]) for r in rows] == [("000000", "000001"), ("000001", "000000")]
    assert float(rows[0]["iou"]) == 1.0 and [r["grid"] for r in rows] == ["64", "32"]  # only the copy is refined
    assert float(rows[1]["iou"]) == pytest.approx((24 / 28) ** 3, abs=1e-6)
    text = (out / "near_duplicates.md").read_text()
    low, mid = (24 / 28) ** 3, ((24 / 28) ** 3 + 1) / 2  # min; median = mean of two
    assert f"| test | 2 | 3 | {low:.3f} | {mid:.3f} | {mid:.3f} | 1.000 | 1 | 1 | 1 |" in text
    assert "| [0.6, 0.7) | 1 |" in text and "| [0.9, 1.0] | 1 |" in text
    assert "test: 2 shapes" in capsys.readouterr().out


def test_iou_matrix_against_direct_counts():
    rng = np.random.default_rng(0)
    a, b = rng.random((5, 300)) < 0.3, rng.random((7, 300)) < 0.5
    b[0] = False
    a[1] = False  # an empty row against an empty row: IoU 1, as metrics.functional.iou
    matrix = near.iou_matrix(a, b, block=3)
    for i in range(5):
        for j in range(7):
            union = (a[i] | b[j]).sum()
            assert matrix[i, j] == (1.0 if union == 0 else (a[i] & b[j]).sum() / union)


def test_records_on_disk_without_manifest_and_bad_input(tmp_path, capsys):
    write_dataset(tmp_path / "data", manifest=False)
    out = tmp_path / "report"
    assert near.main([str(tmp_path / "data"), "--out", str(out)]) == 0
    assert "No manifest" in (out / "near_duplicates.md").read_text()
    assert near.main([str(tmp_path / "missing"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "dataset folder" in err[0] and "missing" in err[0]


def plate(z_centre):
    return trimesh.creation.box(extents=[0.8, 0.8, 0.02]).apply_translation([0, 0, z_centre])


def test_thin_shapes_that_match_on_the_coarse_grid_are_refined(tmp_path):
    """Plates z in [0, 0.02] and [0.005, 0.025]: both hold the one 32^3 centre z = 1/64, so IoU 1 there;
    on 64^3 the first holds z = 1/128 only, the second 1/128 and 3/128 (52 x 52 centres in x, y): IoU 1/2."""
    root = tmp_path / "data"
    for split, mesh in (("train", plate(0.01)), ("test", plate(0.015))):
        path = record_path(root, split, "000000")
        path.parent.mkdir(parents=True)
        write_record(path, {"vertices": mesh.vertices.astype(np.float32), "faces": mesh.faces.astype(np.int32)})
    (root / "manifest.json").write_text(json.dumps({"format": FORMAT, "splits": {"train": ["000000"], "test": ["000000"]}}))
    results = near.run(root, ["test"], 32, tmp_path / "out", refine_resolution=64)
    assert results["test"]["coarse"][0] == 1.0 and results["test"]["iou"][0] == 0.5
    results = near.run(root, ["test"], 32, tmp_path / "out", refine_resolution=0)
    assert results["test"]["iou"][0] == 1.0
