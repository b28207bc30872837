"""bench/train_throughput.py's grid comparison: it times what each grid's Stage 1 and Stage 2 train with."""

import importlib.util
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("train_throughput", REPO / "bench" / "train_throughput.py")
bench = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench)


@pytest.mark.parametrize("grid, stage, expected", [
    ("table1-medium", "stage1", {"model_args": {}, "points": {"surface": 2048, "sdf": 2048}, "bf16": False, "batch": 16}),
    ("table1-medium", "stage2", {"model_args": {}, "points": None, "bf16": False, "batch": 16}),
    ("table1-medium-fast", "stage1",
     {"model_args": {"lr_decay_steps": 500}, "points": {"surface": 1024, "sdf": 2048}, "bf16": True, "batch": 16}),
    ("table1-medium-fast", "stage2", {"model_args": {"encoder_stem_stride": 2}, "points": None, "bf16": False, "batch": 16}),
    ("table1-medium-faster", "stage1", {"model_args": {"lr_decay_steps": 500, "unet_channels": 8},
                                        "points": {"surface": 512, "sdf": 1024}, "bf16": True, "batch": 32}),
    ("table1-medium-faster", "stage2", {"model_args": {"encoder_stem_stride": 2, "encoder_width": 0.125},
                                        "points": None, "bf16": True, "batch": 32}),
])
def test_grid_settings_are_the_grids_own(grid, stage, expected, monkeypatch):
    monkeypatch.chdir(REPO)
    assert bench.grid_settings(grid, stage) == expected


def test_build_takes_the_settings_into_model_and_batch():
    model, batch = bench.build("stage1", batch=2, model_args={"lr_decay_steps": 500}, points={"surface": 1024, "sdf": 2048})
    assert model.hparams.lr_decay_steps == 500
    assert batch["surface_points"].shape == (2, 1024, 3) and batch["sdf_values"].shape == (2, 2048)
    model, batch = bench.build("stage2", batch=2, model_args={"encoder_stem_stride": 2})
    assert model.radar_encoder.resnet.features[0].stride == (2, 2) and batch["sdf_points"].shape == (2, 4096, 3)


def test_fit_steps_timer_averages_the_steps_between_its_bounds_and_stops_the_fit(monkeypatch):
    spec = importlib.util.spec_from_file_location("fit_steps", REPO / "bench" / "fit_steps.py")
    fit_steps = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fit_steps)
    clock = iter([10.0, 16.0])
    monkeypatch.setattr(fit_steps.time, "perf_counter", lambda: next(clock))
    timer, trainer = fit_steps.StepTimer(2, 5), type("Trainer", (), {"should_stop": False})()
    for step in range(1, 6):
        trainer.global_step = step
        timer.on_train_batch_end(trainer, None, None, None, step)
        assert trainer.should_stop == (step == 5)
    assert timer.seconds == 2.0  # 6 s over the 3 steps from 2 to 5
    labels = [label for label, _ in fit_steps.STEPS["stage2"]]
    assert labels[0].startswith("table1-medium as committed") and fit_steps.STEPS["stage2"][0][1] == [fit_steps.LIGHTNING_EMA]
