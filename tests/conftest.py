"""Test-wide settings: no wandb, few threads, and where the shared validation data lives."""

import os
from pathlib import Path

import pytest

os.environ["WANDB_MODE"] = "disabled"
os.environ.setdefault("WANDB_SILENT", "true")

REPO_ROOT = Path(__file__).resolve().parents[1]


def validation_dir() -> Path:
    """../shared/validation beside the checkout, or $RADAR2SHAPE_VALIDATION."""
    return Path(os.environ.get("RADAR2SHAPE_VALIDATION", REPO_ROOT.parent / "shared" / "validation"))


@pytest.fixture
def shared_validation() -> Path:
    """The validation folder; skips the test (with the reason) when it is absent."""
    path = validation_dir()
    if not path.is_dir():
        pytest.skip(f"shared validation data not found at {path}")
    return path
