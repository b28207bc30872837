"""The ``monocone`` family: a cone with a spherically blunted nose, the paper's measured target shape.

The solid of revolution about z has a flat base of radius ``R`` at ``z = 0``, a conical side of
half-angle ``alpha`` and a spherical nose of radius ``r_n = nose_ratio * R`` tangent to the cone,
nose at +z (so aspect 0 is nose-on). With the virtual apex at ``z_a = R / tan(alpha)`` the nose
centre is at ``z_c = z_a - r_n / sin(alpha)``, the tangent circle at
``(r_n cos(alpha), z_c + r_n sin(alpha))`` and the tip at ``z_c + r_n``, so the height is
``H = R / tan(alpha) - r_n (1 / sin(alpha) - 1)``. The profile is the base corner, then
``nose_segments + 1`` points on the nose arc from the tangent point to the tip; it is resampled
to ``profile_points`` like the frusta profiles, so profile models trained on frusta read it as is.
Each option is a number or a ``[low, high]`` range drawn uniformly per shape.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from radar2shape.errors import UserInputError
from radar2shape.geometry.families.base import Family, Shape, ShapeTask, procedural_tasks
from radar2shape.geometry.profile import profile_to_mesh, resample_profile

Range = float | list[float] | tuple[float, float]


@dataclass(frozen=True)
class Monocone:
    """One blunted cone: base radius, cone half-angle (radians) and nose radius, in mesh units."""

    base_radius: float
    half_angle: float
    nose_radius: float

    def __post_init__(self):
        if not (self.base_radius > 0 and 0 < self.half_angle < np.pi / 2 and 0 <= self.nose_radius):
            raise UserInputError(f"monocone: need base_radius > 0, 0 < half angle < 90 deg, nose radius >= 0, got {self}")
        if self.nose_radius * np.cos(self.half_angle) >= self.base_radius:
            raise UserInputError(f"monocone: the nose (radius {self.nose_radius:g}) is wider than the base "
                                 f"(radius {self.base_radius:g}); lower nose_ratio")

    @property
    def nose_centre_z(self) -> float:
        return self.base_radius / np.tan(self.half_angle) - self.nose_radius / np.sin(self.half_angle)

    @property
    def height(self) -> float:
        """Base to tip."""
        return self.nose_centre_z + self.nose_radius

    @property
    def tangent(self) -> tuple[float, float]:
        """(r, z) where the cone meets the nose sphere."""
        a = self.half_angle
        return self.nose_radius * np.cos(a), self.nose_centre_z + self.nose_radius * np.sin(a)

    @property
    def volume(self) -> float:
        """Closed form: the frustum up to the tangent circle plus the spherical cap above it."""
        r_t, z_t = self.tangent
        cap = self.nose_radius * (1.0 - np.sin(self.half_angle))
        frustum = np.pi * z_t / 3.0 * (self.base_radius**2 + self.base_radius * r_t + r_t**2)
        return float(frustum + np.pi * cap**2 * (3.0 * self.nose_radius - cap) / 3.0)

    def profile(self, nose_segments: int = 8) -> np.ndarray:
        """(r, z) from the base corner over the cone to the tip; the nose arc in ``nose_segments`` pieces."""
        if self.nose_radius == 0:
            return np.array([[self.base_radius, 0.0], [0.0, self.height]])
        theta = np.linspace(self.half_angle, np.pi / 2, nose_segments + 1)
        arc = np.column_stack([self.nose_radius * np.cos(theta), self.nose_centre_z + self.nose_radius * np.sin(theta)])
        arc[-1, 0] = 0.0
        return np.vstack([[self.base_radius, 0.0], arc])


def _draw(value: Range, rng: np.random.Generator, name: str) -> float:
    if isinstance(value, (int, float)):
        return float(value)
    try:
        low, high = map(float, value)
    except (TypeError, ValueError):
        raise UserInputError(f"monocone option {name}: expected a number or [low, high], got {value!r}") from None
    if high < low:
        raise UserInputError(f"monocone option {name}: [low, high] with low <= high, got {value!r}")
    return float(rng.uniform(low, high))


class MonoconeFamily(Family):
    """Blunted cones with random base radius, half-angle and nose ratio; one class, roll symmetric about z."""

    name = "monocone"
    roll_symmetric = True

    def __init__(self, base_radius: Range = 0.5, half_angle_deg: Range = (10.0, 25.0), nose_ratio: Range = (0.1, 0.4),
                 nose_segments: int = 8, profile_points: int = 16, segments: int = 64):
        if nose_segments + 3 > profile_points:
            raise UserInputError(f"monocone: nose_segments + 3 = {nose_segments + 3} corners exceed "
                                 f"profile_points = {profile_points}")
        self.class_names = ["monocone"]
        self.base_radius, self.half_angle_deg, self.nose_ratio = base_radius, half_angle_deg, nose_ratio
        self.nose_segments, self.profile_points, self.segments = nose_segments, profile_points, segments

    def plan(self, num, splits, seed):
        return procedural_tasks(num, splits, seed, self.class_names)

    def cone(self, seed: int) -> Monocone:
        """The monocone of ``seed`` (the task seed)."""
        rng = np.random.default_rng(seed)
        radius = _draw(self.base_radius, rng, "base_radius")
        angle = np.radians(_draw(self.half_angle_deg, rng, "half_angle_deg"))
        return Monocone(radius, angle, _draw(self.nose_ratio, rng, "nose_ratio") * radius)

    def generate(self, task: ShapeTask) -> Shape:
        cone = self.cone(task.seed)
        profile = cone.profile(self.nose_segments)
        return Shape(
            mesh=profile_to_mesh(profile, self.segments),
            provenance={"generator": self.name, "seed": task.seed, "base_radius": cone.base_radius,
                        "half_angle_deg": float(np.degrees(cone.half_angle)), "nose_radius": cone.nose_radius},
            profile=resample_profile(profile, self.profile_points),
        )
