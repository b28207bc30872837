"""Helpers and fixtures of the fault tests: the CLI as a child process, a tiny build config, a
reference dataset built on the normal disk, a small tmpfs to fill.

A plain module the tests import (fixtures included), not a conftest.py: other folders' tests import
their own ``conftest`` by name, which a second conftest module would shadow."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
# Six parts shapes with few faces and points: a record is ~60 kB, a build takes seconds.
TINY_YAML = """\
family: parts
family_options: {segments: 8}
seed: 0
num: 6
splits: {train: 0.5, val: 0.25, test: 0.25}
mesh: {face_budget: 1000, remesh_resolution: 32}
sampling: {surface: 512, eval: 512, sdf: 1024, occ: 1024}
radar:
  aspect_deg: {start: 0.0, stop: 180.0, count: 8}
  roll_deg: {start: 0.0, stop: 360.0, count: 8, endpoint: false}
  freq_ghz: {start: 8.0, stop: 12.0, count: 16}
  size_m: 1.0
"""


def radar2shape(*args: str, cwd: Path | None = None, timeout: float = 300, **env: str) -> subprocess.CompletedProcess:
    """``radar2shape ARGS`` as a child process (one thread, no wandb), output captured."""
    environment = {**os.environ, "WANDB_MODE": "disabled", "OMP_NUM_THREADS": "1", **env}
    return subprocess.run([sys.executable, "-m", "radar2shape.cli", *map(str, args)], cwd=cwd or REPO,
                          capture_output=True, text=True, timeout=timeout, env=environment)


def one_error_line(result: subprocess.CompletedProcess, tool: bool = True) -> str:
    """The single ``error:`` line of a failed command; a tool command prints nothing else on stderr."""
    assert "Traceback" not in result.stderr, result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1, result.stderr
    if tool:
        assert result.stderr.strip() == errors[0], result.stderr
    return errors[0]


def leftovers(folder: Path) -> list[str]:
    """Temporary files of the atomic writer (``.NAME.PID.HEX.tmp...``) under ``folder``."""
    return sorted(str(p) for p in folder.rglob("*") if ".tmp" in p.name)


def files_of(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def fill(disk: Path, leave: int) -> Path:
    """Write a filler file so that about ``leave`` bytes stay free on ``disk``; returns it."""
    filler = disk / "filler.bin"
    free = shutil.disk_usage(disk).free
    with open(filler, "wb") as handle:
        handle.write(b"\0" * max(0, free - leave))
    assert abs(shutil.disk_usage(disk).free - leave) <= 8192
    return filler


@pytest.fixture(scope="session")
def tiny_config(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("config") / "tiny.yaml"
    path.write_text(TINY_YAML)
    return path


@pytest.fixture(scope="session")
def reference_dataset(tmp_path_factory, tiny_config) -> Path:
    """The tiny dataset built without faults on the normal disk: what every rerun must equal."""
    root = tmp_path_factory.mktemp("reference") / "data"
    result = radar2shape("build-data", "--config", tiny_config, "--out", root, "--quiet")
    assert result.returncode == 0, result.stderr
    return root


@pytest.fixture
def small_disk(tmp_path) -> Path:
    """A 2 MB tmpfs (needs the right to mount, e.g. root in a container); unmounted afterwards."""
    mount = tmp_path / f"small-{uuid.uuid4().hex[:6]}"
    mount.mkdir()
    if shutil.which("mount") is None:
        pytest.skip("no mount command: cannot make a small file system to fill")
    probe = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mount)], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"mounting a tmpfs is not permitted here ({probe.stderr.strip() or probe.returncode}); "
                    "the full-disk tests need it")
    try:
        yield mount
    finally:
        if subprocess.run(["umount", str(mount)], capture_output=True).returncode != 0:
            subprocess.run(["umount", "-l", str(mount)], capture_output=True)
