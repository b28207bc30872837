"""Tiny datasets built once per test session (conf/data/*_tiny.yaml with fewer shapes)."""

import subprocess
import sys
from pathlib import Path

import pytest

from data_modules.build import build_dataset
from data_modules.config import load_build_config

REPO = Path(__file__).resolve().parents[2]
TINY = {"parts": REPO / "conf/data/parts_tiny.yaml", "frusta": REPO / "conf/data/frusta_tiny.yaml"}


def tiny_config(name: str, num: int):
    """The tiny config of family ``name`` with ``num`` shapes."""
    return load_build_config(TINY[name], num=num)


def run_builder(*args: str, **popen) -> subprocess.Popen:
    """The build-data command in a subprocess (its own process group, so a kill takes the workers too)."""
    command = [sys.executable, "-m", "data_modules.commands.build_data", "--quiet", *args]
    return subprocess.Popen(command, cwd=REPO, start_new_session=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **popen)


@pytest.fixture(scope="session")
def parts_dataset(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("parts") / "data"
    build_dataset(tiny_config("parts", 10), root, progress=False)
    return root


@pytest.fixture(scope="session")
def frusta_dataset(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("frusta") / "data"
    build_dataset(tiny_config("frusta", 10), root, progress=False)
    return root
