"""Radar simulation: physical optics (plus SBR bounces and edge currents) on triangle meshes, in
one polarisation or all four, grids, noise, masks and response files.

Conventions (docs/design.md section 4): metres, hertz, radians; u = (sin a cos p, sin a sin p, cos a)
points toward the radar; S is complex with |S|^2 the monostatic RCS in m^2. docs/radar.md has
the formulas, the accuracy checks and the benchmark.
"""

from radar2shape.radar.edges import ALL_POLARIZATIONS, POLARIZATIONS
from radar2shape.radar.grid import RadarGrid
from radar2shape.radar.io import RadarResponse, load_response, save_response
from radar2shape.radar.masks import fixed_window_mask, random_window_mask
from radar2shape.radar.signal import add_noise, to_db
from radar2shape.radar.simulator import simulate
from radar2shape.radar.spec import RadarSpec

__all__ = [
    "ALL_POLARIZATIONS",
    "POLARIZATIONS",
    "RadarGrid",
    "RadarResponse",
    "RadarSpec",
    "add_noise",
    "fixed_window_mask",
    "load_response",
    "random_window_mask",
    "save_response",
    "simulate",
    "to_db",
]
