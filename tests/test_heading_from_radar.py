"""scripts/heading_from_radar.py: a reconstruction is placed by the turn the search returns."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import trimesh

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("heading_from_radar", REPO / "scripts" / "heading_from_radar.py")
heading = importlib.util.module_from_spec(spec)
spec.loader.exec_module(heading)


def test_placed_mesh_is_the_turned_mesh():
    mesh = trimesh.creation.box((0.8, 0.2, 0.1), trimesh.transformations.translation_matrix((0.1, 0.3, 0.0)))
    arrays = {"vertices": np.asarray(mesh.vertices, np.float32), "faces": np.asarray(mesh.faces)}
    turned = heading.placed(arrays, (2, True), np.arange(8) * 2 * np.pi / 8)  # mirror, then a quarter turn
    np.testing.assert_allclose(turned.vertices, np.asarray(mesh.vertices)[:, [1, 0, 2]], atol=1e-6)  # (x, y) -> (y, x)
    assert turned.volume == pytest.approx(mesh.volume, rel=1e-6)  # faces stay outward after the mirror
