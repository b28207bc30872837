"""bench/omp_wait.py: each line's fit sees exactly its own OpenMP variables, and its step time is read back."""

import argparse
import importlib.util
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("omp_wait", REPO / "bench" / "omp_wait.py")
bench = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench)

FIT_STEPS_OUTPUT = ("| stage | change (each line adds to the line above) | s/step | x first line |\n|---|---|---|---|\n"
                    "| stage2 | stride-2 stem of the radar ResNet (table1-medium-fast) | 0.091 | 1.00x |\n")


def test_each_setting_replaces_the_callers_variables(monkeypatch):
    monkeypatch.setenv("OMP_WAIT_POLICY", "ACTIVE")
    monkeypatch.setenv("GOMP_SPINCOUNT", "7")
    seen = []

    def fake_run(command, env, **kwargs):
        seen.append((command, {k: env.get(k) for k in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}))
        return subprocess.CompletedProcess(command, 0, FIT_STEPS_OUTPUT, "")

    monkeypatch.setattr(bench.subprocess, "run", fake_run)
    args = argparse.Namespace(skip=5, steps=10, threads=2)
    assert bench.time_setting("stage2", {"GOMP_SPINCOUNT": "10000"}, 0, args) == pytest.approx(0.091)
    assert bench.time_setting("stage2", {"OMP_WAIT_POLICY": "PASSIVE"}, 0, args) == pytest.approx(0.091)
    assert [env for _, env in seen] == [{"OMP_WAIT_POLICY": None, "GOMP_SPINCOUNT": "10000"},
                                        {"OMP_WAIT_POLICY": "PASSIVE", "GOMP_SPINCOUNT": None}]
    assert "--fast-only" in seen[0][0] and seen[0][0][seen[0][0].index("--steps") + 1] == "10"


def test_a_failed_fit_is_reported_not_read_as_a_time(monkeypatch):
    monkeypatch.setattr(bench.subprocess, "run",
                        lambda command, env, **kwargs: subprocess.CompletedProcess(command, 1, "", "boom"))
    with pytest.raises(RuntimeError, match="exit 1"):
        bench.time_setting("stage2", {}, 0, argparse.Namespace(skip=5, steps=10, threads=2))
