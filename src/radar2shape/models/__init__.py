"""LightningModules of the method; every one implements :class:`ReconstructionModel`."""

from radar2shape.models.base import Reconstruction, ReconstructionModel

__all__ = ["Reconstruction", "ReconstructionModel"]
