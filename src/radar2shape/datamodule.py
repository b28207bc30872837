"""The DataModule base the Lightning CLI accepts, so every DataModule can tell its radar spec.

Models adopt the training data's radar spec at fit start (``ReconstructionModel.on_fit_start``)
and store it in every checkpoint; a DataModule without a radar (e.g. the toy spheres) says None.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import lightning as L

if TYPE_CHECKING:
    from radar2shape.radar.spec import RadarSpec


class ReconstructionDataModule(L.LightningDataModule):
    """A LightningDataModule of reconstruction batches; radar DataModules override :attr:`radar_spec`."""

    @property
    def radar_spec(self) -> RadarSpec | None:
        """The radar grid and dB normalisation of this data (None: nothing to check or store)."""
        return None
