"""Reference "models" that learn nothing: the floor any radar-to-shape model must beat.

- :class:`NearestNeighbourReference`: the training shape whose radar is closest to the input
  (L2 over the observed cells of the normalised dB image): what memorising the training set
  and looking the answer up achieves.
- :class:`MeanShapeReference`: one mesh for every input, the voxel-wise majority of the training
  shapes (mean occupancy on a grid thresholded at 0.5, surface placed to sub-voxel accuracy):
  what ignoring the radar achieves.

Both read the training records through the DataModule when a Trainer attaches them
(``datamodule.train_records()`` for the meshes and radar, ``datamodule.radar_spec`` for the dB
normalisation), and implement :class:`ReconstructionModel`, so ``radar2shape test``
scores them with the same callback as every model. Nothing is trained: run them with
``radar2shape test`` only.
"""

from __future__ import annotations


import numpy as np
import torch
import trimesh

from radar2shape.errors import UserInputError
from radar2shape.models.base import Reconstruction, ReconstructionModel


def record_mesh(record: dict) -> trimesh.Trimesh:
    """The normalised watertight mesh stored in a dataset record."""
    return trimesh.Trimesh(record["vertices"], record["faces"], process=False)


def training_records(datamodule):
    """``datamodule.train_records()``, with an error that says what a reference needs."""
    if datamodule is None or not callable(getattr(datamodule, "train_records", None)):
        raise UserInputError(
            "reference models read the training set through the DataModule's train_records(); "
            f"got {type(datamodule).__name__} (use data_modules.ShapeDataModule)"
        )
    records = datamodule.train_records()
    if len(records) == 0:
        raise UserInputError("reference models need at least one training record")
    return records


class _Reference(ReconstructionModel):
    """Shared plumbing: build from the DataModule once, in ``setup``; no losses and no parameters to optimise."""

    def __init__(self) -> None:
        super().__init__()
        self._ready = False

    def setup(self, stage: str) -> None:
        if not self._ready:
            self.fit_reference(self.trainer.datamodule)

    def fit_reference(self, datamodule) -> None:
        """Read what the reference needs from the training set; sets ``_ready``."""
        raise NotImplementedError

    def _check_ready(self) -> None:
        if not self._ready:
            raise RuntimeError(f"{type(self).__name__}.fit_reference(datamodule) has not run (attach it to a Trainer)")

    def losses(self, batch: dict) -> dict[str, torch.Tensor]:
        """Nothing is trained, so there is nothing to log; scores come from :meth:`reconstruct`."""
        return {}


class NearestNeighbourReference(_Reference):
    """The mesh of the training shape whose dB response is closest to the input's over its observed cells.

    The training responses are normalised by the DataModule's radar spec (every cell observed, no
    noise), exactly like the inputs. Distances use
    ``|m.(x - y)|^2 = |x|^2 - 2 x.y + m.y^2`` (masked input cells are 0), three matrix products.
    Args: chunk: training responses compared per matrix product (bounds memory).
    """

    def __init__(self, chunk: int = 256) -> None:
        super().__init__()
        self.save_hyperparameters()

    def fit_reference(self, datamodule) -> None:
        records = training_records(datamodule)
        spec = datamodule.radar_spec
        radar = [spec.normalise(spec.to_db(records[i]["radar"])) for i in range(len(records))]
        self._radar = torch.from_numpy(np.stack(radar))
        self._records = records
        self._ready = True

    @torch.no_grad()
    def neighbours(self, radar: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Index ``[B]`` of the closest training response to each input ``[B, A, R, F]`` with mask ``[B, A, R]``."""
        self._check_ready()
        if tuple(radar.shape[1:]) != tuple(self._radar.shape[1:]):
            shapes = f"{tuple(radar.shape[1:])} and training radar {tuple(self._radar.shape[1:])}"
            raise UserInputError(f"input radar {shapes} differ")
        x = (radar * mask[..., None]).flatten(1).double().cpu()
        m = mask.flatten(1).double().cpu()
        best_distance = torch.full((len(x),), float("inf"), dtype=torch.float64)
        best = torch.zeros(len(x), dtype=torch.long)
        for start in range(0, len(self._radar), self.hparams.chunk):
            y = self._radar[start:start + self.hparams.chunk].double()
            distance = (x * x).sum(1, keepdim=True) - 2 * x @ y.flatten(1).T + m @ (y * y).sum(-1).flatten(1).T
            value, index = distance.min(dim=1)
            better = value < best_distance
            best_distance[better], best[better] = value[better], index[better] + start
        return best

    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        index = self.neighbours(batch["radar"], batch["radar_mask"])
        return [Reconstruction(mesh=record_mesh(self._records[int(i)])) for i in index]


def quantile_from_counts(counts: np.ndarray, values: np.ndarray, q: float) -> np.ndarray:
    """Per row of a histogram ``counts [P, B]`` over bin ``values [B]``: the ``q``-quantile value."""
    cumulative = np.cumsum(counts, axis=1)
    target = q * cumulative[:, -1:]
    return values[np.minimum((cumulative < target).sum(axis=1), len(values) - 1)]


class MeanShapeReference(_Reference):
    """Every input gets the same mesh: the cells that at least ``level`` of the training shapes fill.

    That is the mean training occupancy thresholded at ``level`` (default 0.5, a majority vote).
    To place its surface to sub-voxel accuracy (binary occupancy would put it up to a voxel off),
    each shape contributes its SDF truncated to one voxel, ``clip(sdf / voxel, -1, 1)``, on a
    ``resolution^3`` grid over ``[-bound, bound]^3`` (padded past the unit cube so the surface
    closes), and the mesh is the zero set of their ``level``-quantile (the median for 0.5): it is
    negative exactly where at least that fraction of shapes is inside. The distance is to the
    record's surface samples, the sign from the metrics' containment routine; the quantile is read
    from a per-point histogram, so memory does not grow with the number of shapes.
    """

    reads_radar = False  # one mesh for every input

    BINS = 65  # histogram bins over [-1, 1] voxel: quantile resolution 1/32 voxel

    def __init__(self, resolution: int = 48, bound: float = 0.55, level: float = 0.5) -> None:
        super().__init__()
        self.save_hyperparameters()

    def fit_reference(self, datamodule) -> None:
        from radar2shape.geometry.marching_cubes import grid_points, sdf_grid_to_mesh
        from radar2shape.geometry.query import contains, nearest_distance

        records = training_records(datamodule)
        res, bound = int(self.hparams.resolution), float(self.hparams.bound)
        points = grid_points(res, (-bound, bound))
        voxel = 2 * bound / (res - 1)
        counts = np.zeros((len(points), self.BINS), dtype=np.int32)
        row_start = np.arange(len(points)) * self.BINS
        for i in range(len(records)):
            record = records[i]
            sign = np.where(contains(record_mesh(record), points), -1.0, 1.0)
            near = nearest_distance(points, record["surface_points"], upper_bound=voxel)  # inf past a voxel
            sdf = sign * np.clip(near / voxel, 0.0, 1.0)
            counts.reshape(-1)[row_start + np.rint((sdf + 1) / 2 * (self.BINS - 1)).astype(int)] += 1  # one bin per row
        field = quantile_from_counts(counts, np.linspace(-1.0, 1.0, self.BINS), float(self.hparams.level))
        self.mesh = sdf_grid_to_mesh(field.reshape(res, res, res), (-bound, bound))
        self._ready = True

    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        self._check_ready()
        return [Reconstruction(mesh=self.mesh.copy()) for _ in range(len(batch["radar"]))]
