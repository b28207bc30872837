"""Exact roll augmentation of a training sample: turn about z by whole roll steps, and mirror.

Turning an object about z by one roll step is an exact circular shift of its response along roll,
and mirroring it through the xz plane (y -> -y) reverses roll (r -> -r mod R) (docs/design.md
section 4; tests/radar/test_symmetry.py checks both on the simulator). So a record gives 2R exact
samples for free: the radar is re-indexed and every point set is moved the same way, with no
re-simulation and no re-sampling.

The transform is ``x -> Rz(shift * 2 pi / R) @ M @ x`` with ``M = diag(1, -1, 1)`` when
``mirror`` (else identity). Signed distances and containment labels do not change; normals move
like points; mesh faces reverse their order under a mirror so they stay outward. float16
occupancy positions come back as float32: rounding the turned points again could move a point
near the surface across it, away from its label.
"""

from __future__ import annotations

import numpy as np

from radar2shape.radar.heading import roll_order, turn_rotation

POINT_KEYS = ("vertices", "surface_points", "surface_normals", "sdf_points", "occ_points", "eval_points")


def turn_and_mirror(sample_arrays: dict, shift: int, mirror: bool, roll_rad=None) -> dict:
    """A copy of ``sample_arrays`` turned by ``shift`` roll steps about z, after a mirror y -> -y if asked.

    ``radar`` is indexed ``[A, R, ...]``; ``roll_rad`` (the record's, or the argument) gives R.
    Keys not listed in ``POINT_KEYS``, ``radar``, ``radar_mask`` or ``faces`` are copied unchanged.
    """
    out = dict(sample_arrays)
    roll = sample_arrays.get("roll_rad") if roll_rad is None else roll_rad
    if roll is None:
        raise ValueError("turn_and_mirror needs the roll axis (roll_rad)")
    order = roll_order(roll, shift, mirror)
    for key in ("radar", "radar_mask"):
        if key in sample_arrays and np.ndim(sample_arrays[key]) >= 2:
            out[key] = np.asarray(sample_arrays[key])[:, order]
    rotation = turn_rotation(len(order), shift, mirror)
    for key in POINT_KEYS:
        if key in sample_arrays:
            points = np.asarray(sample_arrays[key])
            dtype = np.float32 if points.dtype == np.float16 else points.dtype  # float16 would move points off their labels
            out[key] = (points.astype(np.float64) @ rotation.T).astype(dtype)
    if mirror and "faces" in sample_arrays:
        out["faces"] = np.ascontiguousarray(np.asarray(sample_arrays["faces"])[:, ::-1])
    return out
