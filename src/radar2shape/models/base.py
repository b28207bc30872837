"""The one reconstruction interface every model (ours and baselines) implements.

Metric callbacks only talk to this interface, so a metric never knows which model it scores.
"""

from __future__ import annotations

from dataclasses import dataclass

import lightning as L
import numpy as np
import trimesh


@dataclass
class Reconstruction:
    """A predicted shape in normalised coordinates (unit cube [-0.5, 0.5]^3).

    Exactly what the model produces: a surface mesh, or a point set for point-cloud models.
    """

    mesh: trimesh.Trimesh | None = None
    points: np.ndarray | None = None

    @property
    def is_empty(self) -> bool:
        """True when there is nothing to score (no faces and no points)."""
        has_mesh = self.mesh is not None and len(self.mesh.faces) > 0
        has_points = self.points is not None and len(self.points) > 0
        return not (has_mesh or has_points)


class ReconstructionModel(L.LightningModule):
    """A LightningModule that can turn a batch into one reconstruction per sample."""

    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        """Return one :class:`Reconstruction` per sample of ``batch`` (same order)."""
        raise NotImplementedError(f"{type(self).__name__} must implement reconstruct(batch)")
