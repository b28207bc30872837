"""How well a reconstruction explains the radar it came from: a confidence that needs no ground truth.

The reconstruction (normalised frame, the unit cube) is put back at the radar spec's object size,
simulated with physical optics on the input's grid, and compared with the input over the observed
cells only, in linear power after one free gain (the calibration offset a measurement may carry):

    r = || P - g Q || / || P ||,   g = <P, Q> / <Q, Q>,

with P the observed power |S|^2 and Q the simulated one. r is 0 for a perfect match and at most 1
(g = 0 already gives 1). A smooth reconstruction differs from the true shape in fine interference
structure whatever its IoU, so r cannot rank samples of one shape; across shapes it says which
reconstructions are poor (docs/metrics.md, "Radar consistency").
"""

from __future__ import annotations

import numpy as np

# Faces the reconstruction is simplified to before it is simulated: the records' own face budget
# (conf/data/parts_medium.yaml), so a re-simulation costs what a record's simulation cost.
MAX_FACES = 8000


def power_residual(observed_db: np.ndarray, simulated_power: np.ndarray, mask: np.ndarray) -> float:
    """``r`` above for dB ``observed_db [A, R, F]`` (NaN: no value), power ``simulated_power`` of the
    same shape, and the observed cells ``mask [A, R]``."""
    select = np.asarray(mask, dtype=bool)[..., None] & np.isfinite(observed_db)
    p = np.power(10.0, observed_db[select] / 10.0, dtype=np.float64)
    q = np.asarray(simulated_power, dtype=np.float64)[select]
    if p.size == 0 or not np.any(p > 0):
        return float("nan")
    qq = float(q @ q)
    gain = float(p @ q) / qq if qq > 0 else 0.0
    return float(np.linalg.norm(p - gain * q) / np.linalg.norm(p))


def radar_consistency(mesh, observed_db: np.ndarray, mask: np.ndarray, spec) -> float:
    """``r`` of ``mesh`` (normalised frame) against the input ``observed_db`` on ``spec``'s grid."""
    import trimesh

    from radar2shape.geometry.simplify import simplify
    from radar2shape.radar import simulate

    if mesh is None or len(mesh.faces) == 0:
        return float("nan")
    small = simplify(mesh, MAX_FACES) if len(mesh.faces) > MAX_FACES else mesh
    at_size = trimesh.Trimesh(np.asarray(small.vertices) * spec.grid.size_m, small.faces, process=False)
    response = simulate(at_size, spec.grid.aspect_rad, spec.grid.roll_rad, spec.grid.freq_hz)
    return power_residual(observed_db, np.abs(response) ** 2, mask)
