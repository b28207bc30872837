"""The reconstruction every model returns, in a module light enough for the tool commands.

It lives apart from ``models.base`` (which needs Lightning and torch) so that scoring and
``radar2shape evaluate`` start without importing them; ``models.base`` re-exports it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh


@dataclass
class Reconstruction:
    """A predicted shape in normalised coordinates (unit cube [-0.5, 0.5]^3).

    Exactly what the model produces: a surface mesh, or a point set for point-cloud models;
    ``profile`` is the (r, z) outline of roll-symmetric predictions (None otherwise);
    ``predicted_iou`` the model's own estimate of its IoU (a verifier's; None when it makes none),
    which the evaluator logs beside the true IoU.
    """

    mesh: trimesh.Trimesh | None = None
    points: np.ndarray | None = None
    profile: np.ndarray | None = None
    predicted_iou: float | None = None

    @property
    def is_empty(self) -> bool:
        """True when there is nothing to score (no faces and no points)."""
        has_mesh = self.mesh is not None and len(self.mesh.faces) > 0
        has_points = self.points is not None and len(self.points) > 0
        return not (has_mesh or has_points)
