"""The ``frusta`` family: roll-symmetric stacks of 1-5 frusta, described by (r, z) profiles.

A stack has random heights and radii; each interface between frusta is continuous or a flat
step (two radii at one z); each end is a flat cap or a point (cone tip). The class is the
number of frusta. Profiles are stored resampled to ``profile_points`` points (all corners
kept, see ``geometry.profile``); five frusta with steps need at most 12 corners, so the
default of 16 always fits.
"""

from __future__ import annotations

import numpy as np

from radar2shape.geometry.families.base import Family, Shape, ShapeTask, procedural_tasks
from radar2shape.geometry.profile import profile_to_mesh, resample_profile


def random_profile(rng: np.random.Generator, n_frusta: int, step_probability: float = 0.3,
                   point_probability: float = 0.3) -> np.ndarray:
    """A random stack profile of ``n_frusta`` frusta, bottom to top, as (r, z) points."""
    z = np.concatenate([[0.0], np.cumsum(rng.uniform(0.2, 1.0, n_frusta))])
    radius = rng.uniform(0.1, 0.6, size=(n_frusta + 1, 2))  # per interface: radius below, above
    pointed = rng.random(2) < point_probability
    if n_frusta == 1:
        pointed[1] &= ~pointed[0]  # a single frustum with two tips would enclose nothing
    points = [(0.0 if pointed[0] else radius[0, 1], z[0])]
    for k in range(1, n_frusta):
        points.append((radius[k, 0], z[k]))
        if rng.random() < step_probability:
            points.append((radius[k, 1], z[k]))
    points.append((0.0 if pointed[1] else radius[-1, 0], z[-1]))
    return np.asarray(points)


class FrustaFamily(Family):
    """Stacks of frusta; roll symmetric about z."""

    name = "frusta"
    roll_symmetric = True

    def __init__(self, max_frusta: int = 5, profile_points: int = 16, segments: int = 64,
                 step_probability: float = 0.3, point_probability: float = 0.3):
        self.class_names = [f"frusta{k}" for k in range(1, max_frusta + 1)]
        self.profile_points = profile_points
        self.segments = segments
        self.step_probability = step_probability
        self.point_probability = point_probability

    def plan(self, num, splits, seed):
        return procedural_tasks(num, splits, seed, self.class_names)

    def generate(self, task: ShapeTask) -> Shape:
        n_frusta = task.label + 1
        profile = random_profile(np.random.default_rng(task.seed), n_frusta, self.step_probability, self.point_probability)
        return Shape(
            mesh=profile_to_mesh(profile, self.segments),
            provenance={"generator": self.name, "seed": task.seed, "n_frusta": n_frusta},
            profile=resample_profile(profile, self.profile_points),
        )
