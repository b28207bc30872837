"""Solid building blocks for procedural shapes (manifold3d, so every union stays watertight).

Every function returns a ``manifold3d.Manifold`` placed in metres-agnostic model units; shapes
are normalised afterwards. Angles are degrees, as manifold3d takes them.
"""

from __future__ import annotations

from collections.abc import Sequence

import manifold3d as m3
import numpy as np

Vec = Sequence[float]
_AXIS_ROTATION = {"z": (0.0, 0.0, 0.0), "x": (0.0, 90.0, 0.0), "y": (-90.0, 0.0, 0.0)}


def box(size: Vec, at: Vec = (0.0, 0.0, 0.0)) -> m3.Manifold:
    """Axis-aligned box of ``size`` centred at ``at``."""
    return m3.Manifold.cube(list(map(float, size)), center=True).translate(list(map(float, at)))


def cylinder(radius: float, height: float, at: Vec = (0.0, 0.0, 0.0), axis: str = "z",
             radius_top: float | None = None, segments: int = 24) -> m3.Manifold:
    """Cylinder (or frustum/cone with ``radius_top``) centred at ``at`` along ``axis``.

    ``radius_top`` is the radius at the +axis end.
    """
    top = radius if radius_top is None else radius_top
    solid = m3.Manifold.cylinder(float(height), float(radius), float(top), int(segments), center=True)
    return solid.rotate(_AXIS_ROTATION[axis]).translate(list(map(float, at)))


def sphere(radius: float, at: Vec = (0.0, 0.0, 0.0), segments: int = 24) -> m3.Manifold:
    """Sphere of ``radius`` centred at ``at``."""
    return m3.Manifold.sphere(float(radius), int(segments)).translate(list(map(float, at)))


def torus(major: float, minor: float, at: Vec = (0.0, 0.0, 0.0), rotate: Vec = (0.0, 0.0, 0.0),
          segments: int = 24) -> m3.Manifold:
    """Torus about z (ring radius ``major``, tube radius ``minor``), rotated then moved to ``at``."""
    ring = m3.CrossSection.circle(float(minor), int(segments)).translate([float(major), 0.0])
    return m3.Manifold.revolve(ring, int(segments)).rotate(list(map(float, rotate))).translate(list(map(float, at)))


def plate(outline: np.ndarray, thickness: float, plane: str = "xy") -> m3.Manifold:
    """A polygon ``outline`` [n, 2] (either winding) extruded ``thickness`` symmetrically about its plane.

    ``plane`` names the two axes the outline's coordinates map to: "xy" (wings, tail planes) or
    "xz" (fins, cabins, seen from the side).
    """
    outline = np.asarray(outline, dtype=np.float64)
    x, y = outline.T
    if np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)) < 0:  # clockwise: manifold3d would drop it
        outline = outline[::-1]
    solid = m3.Manifold.extrude(m3.CrossSection([outline]), float(thickness)).translate([0.0, 0.0, -thickness / 2])
    return solid if plane == "xy" else solid.rotate([90.0, 0.0, 0.0])


def revolved(profile: np.ndarray, segments: int = 24) -> m3.Manifold:
    """Solid of revolution about z of a closed (r, z) outline [n, 2] (CCW)."""
    return m3.Manifold.revolve(m3.CrossSection([np.asarray(profile, dtype=np.float64)]), int(segments))


def union(*solids: m3.Manifold) -> m3.Manifold:
    """Exact union of all ``solids``."""
    return m3.Manifold.batch_boolean(list(solids), m3.OpType.Add)


def ring_positions(count: int, radius: float, z: float = 0.0, phase: float = 0.0) -> np.ndarray:
    """``count`` points evenly on a horizontal circle (legs, fins, boosters): [count, 3]."""
    angle = phase + 2 * np.pi * np.arange(count) / count
    return np.stack([radius * np.cos(angle), radius * np.sin(angle), np.full(count, z)], axis=1)
