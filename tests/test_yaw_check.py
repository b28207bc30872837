"""scripts/yaw_check.py: the turned mesh it scores against is the user's (turned, then normalised)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import trimesh

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("yaw_check", REPO / "scripts" / "yaw_check.py")
yaw_check = importlib.util.module_from_spec(spec)
spec.loader.exec_module(yaw_check)


def test_turned_mesh_is_rotated_about_z_then_normalised():
    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    quarter = yaw_check.turned(box, 90.0)
    np.testing.assert_allclose(np.ptp(quarter.vertices, axis=0), [0.5, 1.0, 0.25], atol=1e-9)  # x and y swap
    np.testing.assert_allclose(quarter.bounds.mean(axis=0), 0.0, atol=1e-9)
    diagonal = yaw_check.turned(box, 45.0)  # footprint (3/sqrt 2) square, scaled so that its side is 1
    np.testing.assert_allclose(np.ptp(diagonal.vertices, axis=0), [1.0, 1.0, 0.5 * np.sqrt(2) / 3], atol=1e-9)
