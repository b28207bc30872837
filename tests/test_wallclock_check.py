"""scripts/wallclock_check.py: the CPU reference it compares with, the Stage 1 it lifts out of a Stage-2
checkpoint, and the step it reports as reaching that reference."""

import importlib.util
from pathlib import Path

import pytest
import torch

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("wallclock_check", REPO / "scripts" / "wallclock_check.py")
wallclock_check = importlib.util.module_from_spec(spec)
spec.loader.exec_module(wallclock_check)
SHIPPED = REPO / "src/radar2shape/weights/radar2shape_parts_medium.ckpt"


def test_cpu_reference_is_the_last_validation_row_of_the_committed_curves():
    # reports/table1-medium/learning_curves.md: Stage 1 ends 0.7135 at step 3779, Stage 2 seed 0 0.5890 at 5039
    assert wallclock_check.cpu_final("radar2shape_stage1") == (3779, 0.7135)
    assert wallclock_check.cpu_final("radar2shape-full-seed0") == (5039, 0.5890)


def test_extracted_stage1_loads_as_sdfvae_with_the_shipped_weights(tmp_path):
    from radar2shape.models.radar_diffusion import load_stage1

    stage1 = load_stage1(wallclock_check.extract_stage1(SHIPPED, tmp_path / "stage1.ckpt"))
    shipped = torch.load(SHIPPED, map_location="cpu", weights_only=True)["state_dict"]
    state = stage1.state_dict()
    assert state and all(torch.equal(v, shipped[f"stage1.{k}"]) for k, v in state.items())


@pytest.mark.parametrize("rows, expected", [
    ([(4, 314, 0.60, 40.0), (9, 629, 0.72, 80.0)], "Reaches the CPU final at step 629, 80 s after start."),
    ([(4, 314, 0.60, 40.0), (9, 629, 0.7134, 80.0)], "Does not reach the CPU final within the run."),
])
def test_summary_names_the_first_row_at_or_above_the_cpu_final(rows, expected):
    args = type("Args", (), {"minutes": 1.0, "device_name": "test", "loader_workers": 0, "sequential": False, "argv": []})()
    text = wallclock_check.summary("bench", {"stage1-fp32": rows}, {"stage1-fp32": 0}, args)
    assert expected in text and "CPU run's final validation IoU: 0.7135 at step 3779." in text
