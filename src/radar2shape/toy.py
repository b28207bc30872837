"""A tiny built-in problem (sphere radius from its radar) for CLI smoke tests and tutorials.

Spheres are the one shape whose PO radar cross-section has a closed form
(docs/design.md section 5), so the data needs no simulator and no files, and a model that
learns it shows the whole fit/test path works: radar in, mesh out, metrics on top.
"""

from __future__ import annotations

import numpy as np
import torch
import trimesh
from torch import nn
from torch.utils.data import DataLoader, TensorDataset

from radar2shape.datamodule import ReconstructionDataModule
from radar2shape.models.base import Reconstruction, ReconstructionModel

SPEED_OF_LIGHT = 299_792_458.0


def sphere_po_rcs(radius_m: np.ndarray, freq_hz: np.ndarray) -> np.ndarray:
    """PO monostatic RCS (m^2) of a PEC sphere: pi a^2 [1 - sin(2ka)/(ka) + sin^2(ka)/(ka)^2]."""
    ka = 2 * np.pi * freq_hz[None, :] / SPEED_OF_LIGHT * radius_m[:, None]
    return np.pi * radius_m[:, None] ** 2 * (1 - np.sin(2 * ka) / ka + (np.sin(ka) / ka) ** 2)


def _sphere_batch(radii: np.ndarray, freq_hz: np.ndarray, n_eval: int, n_occ: int, rng) -> dict:
    """Radar (dB over frequency) and ground-truth samples for spheres of the given radii."""
    rcs_db = 10 * np.log10(sphere_po_rcs(radii, freq_hz))
    directions = rng.normal(size=(len(radii), n_eval, 3))
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    occ = rng.uniform(-0.55, 0.55, size=(len(radii), n_occ, 3))
    return {
        "radar": torch.tensor((rcs_db + 10.0) / 10.0, dtype=torch.float32),
        "radius": torch.tensor(radii, dtype=torch.float32),
        "eval_points": torch.tensor(directions * radii[:, None, None], dtype=torch.float32),
        "occ_points": torch.tensor(occ, dtype=torch.float32),
        "occ_inside": torch.tensor(np.linalg.norm(occ, axis=-1) < radii[:, None]),
        "label": torch.zeros(len(radii), dtype=torch.long),
        "index": torch.arange(len(radii)),
    }


class ToySphereDataModule(ReconstructionDataModule):
    """Spheres of random radius in the unit cube (object size 1 m per unit) with their PO radar."""

    KEYS = ("radar", "radius", "eval_points", "occ_points", "occ_inside", "label", "index")

    def __init__(
        self,
        num_train: int = 64,
        num_val: int = 16,
        num_freq: int = 16,
        freq_ghz: tuple[float, float] = (8.0, 12.0),
        batch_size: int = 8,
        eval_points: int = 2048,
        occ_points: int = 4096,
        seed: int = 0,
    ):
        super().__init__()
        self.save_hyperparameters()
        self.class_names = ["sphere"]
        self.freq_hz = np.linspace(freq_ghz[0], freq_ghz[1], num_freq) * 1e9

    def _split(self, n: int, offset: int) -> TensorDataset:
        rng = np.random.default_rng(self.hparams.seed + offset)
        radii = rng.uniform(0.1, 0.45, size=n)
        batch = _sphere_batch(radii, self.freq_hz, self.hparams.eval_points, self.hparams.occ_points, rng)
        return TensorDataset(*(batch[k] for k in self.KEYS))

    def setup(self, stage: str | None = None) -> None:
        self.train_set = self._split(self.hparams.num_train, 0)
        self.val_set = self._split(self.hparams.num_val, 1)

    def _loader(self, dataset: TensorDataset, shuffle: bool) -> DataLoader:
        def collate(rows):
            return {k: torch.stack([r[i] for r in rows]) for i, k in enumerate(self.KEYS)}

        return DataLoader(dataset, batch_size=self.hparams.batch_size, shuffle=shuffle, collate_fn=collate)

    def train_dataloader(self) -> DataLoader:
        return self._loader(self.train_set, shuffle=True)

    def val_dataloader(self) -> DataLoader:
        return self._loader(self.val_set, shuffle=False)

    def test_dataloader(self) -> DataLoader:
        return self._loader(self.val_set, shuffle=False)


class ToySphereRegressor(ReconstructionModel):
    """An MLP from the sphere's dB-over-frequency radar to its radius; reconstructs an icosphere."""

    optimizer_class = torch.optim.Adam

    def __init__(self, num_freq: int = 16, mlp_hidden: int = 64, lr: float = 3e-3):
        super().__init__()
        self.save_hyperparameters()
        self.net = nn.Sequential(
            nn.Linear(num_freq, mlp_hidden), nn.ReLU(), nn.Linear(mlp_hidden, mlp_hidden), nn.ReLU(), nn.Linear(mlp_hidden, 1)
        )

    def forward(self, radar: torch.Tensor) -> torch.Tensor:
        return 0.1 + 0.35 * torch.sigmoid(self.net(radar).squeeze(-1))

    def losses(self, batch: dict) -> dict[str, torch.Tensor]:
        radius_l1 = torch.mean(torch.abs(self(batch["radar"]) - batch["radius"]))
        return {"loss": radius_l1, "radius_l1": radius_l1}

    @torch.no_grad()
    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        radii = self(batch["radar"]).cpu().numpy()
        return [Reconstruction(mesh=trimesh.creation.icosphere(3, radius=float(r))) for r in radii]
