"""scripts/per_class_scores.py: per-class means from hand-made per-shape scores; one error line on bad input."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("per_class_scores", REPO / "scripts" / "per_class_scores.py")
per_class_scores = importlib.util.module_from_spec(spec)
spec.loader.exec_module(per_class_scores)


def scores(path: Path, rows: list[tuple[int, int, float]]) -> Path:
    lines = ["index,label,chamfer_l2_x1e3,iou,fscore_1pct"] + [f"{i},{label},1.0,{iou},0.5" for i, label, iou in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_class_means_and_best_per_class(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "manifest.json").write_text(json.dumps({"classes": ["airliner", "ship"]}))
    a = scores(tmp_path / "a.csv", [(0, 0, 0.2), (1, 0, 0.4), (2, 1, 0.9)])
    b = scores(tmp_path / "b.csv", [(0, 0, 0.5), (1, 0, 0.5), (2, 1, float("nan"))])
    out = tmp_path / "per_class.md"
    assert per_class_scores.main(["--data", str(data), "--run", "A", str(a), "--run", "B", str(b), "--out", str(out)]) == 0
    text = out.read_text()
    assert "| airliner (2) | 0.300 | **0.500** |" in text  # (0.2 + 0.4) / 2 against 0.5
    assert "| ship (1) | 0.900 | n/a |" in text  # an undefined score is left out, not counted as 0


def test_ceiling_table_lists_only_the_runs_that_have_one(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    (data / "manifest.json").write_text(json.dumps({"classes": ["airliner", "ship"]}))
    latent = tmp_path / "latent.csv"
    latent.write_text("index,label,chamfer_l2_x1e3,iou,fscore_1pct,ceiling_iou\n0,0,1.0,0.2,0.5,0.25\n"
                      "1,0,1.0,0.4,0.5,0.45\n2,1,1.0,0.3,0.5,0.7\n")
    lookup = scores(tmp_path / "lookup.csv", [(0, 0, 0.5), (1, 0, 0.5), (2, 1, 0.1)])
    out = tmp_path / "per_class.md"
    assert per_class_scores.main(["--data", str(data), "--run", "Model", str(latent), "--run", "Lookup", str(lookup),
                                  "--out", str(out)]) == 0
    ceiling = out.read_text().split("### Stage-1 ceiling IoU", 1)[1]
    assert "| class (test shapes) | Model |" in ceiling and "Lookup" not in ceiling
    assert "| airliner (2) | 0.350 |" in ceiling and "| ship (1) | 0.700 |" in ceiling  # (0.25 + 0.45) / 2


def test_a_ceiling_only_file_joins_the_ceiling_table_only(tmp_path, capsys):
    data = tmp_path / "data"
    data.mkdir()
    (data / "manifest.json").write_text(json.dumps({"classes": ["airliner", "ship"]}))
    check = tmp_path / "check.csv"  # scripts/stage1_fit_gap.py --scores: ceilings and labels, no Stage-2 scores
    check.write_text("index,label,ceiling_iou\n0,0,0.6\n1,0,0.4\n2,1,0.9\n")
    latent = tmp_path / "latent.csv"
    latent.write_text("index,label,chamfer_l2_x1e3,iou,fscore_1pct,ceiling_iou\n0,0,1.0,0.2,0.5,0.25\n"
                      "1,0,1.0,0.4,0.5,0.45\n2,1,1.0,0.3,0.5,0.7\n")
    out = tmp_path / "per_class.md"
    assert per_class_scores.main(["--data", str(data), "--run", "Model", str(latent), "--run", "Check", str(check),
                                  "--out", str(out)]) == 0
    text = out.read_text()
    before, ceiling = text.split("### Stage-1 ceiling IoU", 1)
    assert "Check |" not in before.split("Made by")[1].split("### IoU")[1]  # not in the IoU table
    assert "| airliner (2) | 0.350 | **0.500** |" in ceiling and "| ship (1) | 0.700 | **0.900** |" in ceiling
    empty = tmp_path / "empty.csv"
    empty.write_text("index,label,radar_consistency\n0,0,1.0\n")
    assert per_class_scores.main(["--data", str(data), "--run", "E", str(empty), "--out", str(tmp_path / "e.md")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --run E:") and "\n" not in err and not (tmp_path / "e.md").exists()


def test_missing_manifest_is_one_line(tmp_path, capsys):
    assert per_class_scores.main(["--data", str(tmp_path), "--run", "A", "x.csv", "--out", str(tmp_path / "o.md")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --data:") and "\n" not in err
