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


def test_frame_cost_of_a_box_turned_45_degrees_is_its_volume_ratio():
    """A 1 x 0.2 x 0.1 box turned 45 degrees is 1.2 / sqrt 2 wide: normalised in that heading it is
    sqrt 2 / 1.2 times larger and holds the unscaled one (same centre), so IoU = (1.2 / sqrt 2)^3."""
    spec = importlib.util.spec_from_file_location("frame_after_turn", REPO / "scripts" / "frame_after_turn.py")
    frame_after_turn = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(frame_after_turn)
    ratio, iou = frame_after_turn.frame_cost(trimesh.creation.box(extents=(1.0, 0.2, 0.1)), 45.0)
    assert abs(ratio - np.sqrt(2) / 1.2) < 1e-9
    assert abs(iou - (1.2 / np.sqrt(2)) ** 3) < 0.02  # occupancy-sampled
    assert frame_after_turn.frame_cost(trimesh.creation.box(extents=(1.0, 0.2, 0.1)), 0.0) == (1.0, 1.0)


def test_placement_rules_on_an_off_centre_box_turned_45_degrees():
    """A 1 x 0.2 x 0.1 box moved 0.1 along x, turned 45 degrees: turned about the origin its box
    centre is (0.1, 0.1) / sqrt 2; scaled by sqrt 2 / 1.2 it keeps that direction; re-centred it
    sits at the origin; with its own offset kept it sits at the scaled, turned offset."""
    spec = importlib.util.spec_from_file_location("placement_variants", REPO / "scripts" / "placement_variants.py")
    placement_variants = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(placement_variants)
    box = trimesh.creation.box(extents=(1.0, 0.2, 0.1)).apply_translation((0.1, 0.0, 0.0))
    c = np.cos(np.pi / 4)
    rotation = np.array([[c, -c, 0.0], [c, c, 0.0], [0.0, 0.0, 1.0]])
    placed = placement_variants.placements(box.vertices, rotation)
    assert list(placed) == list(placement_variants.RULES)
    centre = {rule: (v.min(axis=0) + v.max(axis=0)) / 2 for rule, v in placed.items()}
    ratio = np.sqrt(2) / 1.2
    np.testing.assert_allclose(centre["turned"], [0.1 * c, 0.1 * c, 0.0], atol=1e-12)
    np.testing.assert_allclose(centre["scaled"], ratio * centre["turned"], atol=1e-12)
    np.testing.assert_allclose(centre["re-centred"], 0.0, atol=1e-12)
    np.testing.assert_allclose(centre["offset kept"], ratio * centre["turned"], atol=1e-12)  # a box: offset = turned offset
    np.testing.assert_allclose(np.ptp(placed["scaled"], axis=0), [1.0, 1.0, 0.1 * ratio], atol=1e-12)
