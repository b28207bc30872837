"""A trained model scored as it is, on any dataset with its radar grid: the shipped model's test row.

``radar2shape test`` builds its model from a config, which a trained checkpoint (the model shipped
in the package above all) does not need: :class:`CheckpointModel` loads one through
:func:`radar2shape.pretrained.load_model` and hands it the test batches, so the same evaluator,
diagnostics and reports score it as every other row. A model normalises its dB input with the
statistics of its own training set, while the DataModule normalises with the test set's; the
batches are put back into the model's normalisation (:func:`renormalise`) before it reads them.
Nothing is trained: run it with ``radar2shape test`` only, e.g.
``--model radar2shape.models.checkpoint_model.CheckpointModel --model.init_args.ckpt default`` (or a
shipped model's name: ``parts``, ``real``).
"""

from __future__ import annotations

import contextvars

import numpy as np
import torch

from radar2shape.errors import UserInputError
from radar2shape.models.base import Reconstruction, ReconstructionModel
from radar2shape.radar.spec import RadarSpec

DEFAULT = "default"  # the default shipped model (radar2shape.pretrained.DEFAULT_NAME)


def renormalise(radar: torch.Tensor, mask: torch.Tensor, source: RadarSpec, target: RadarSpec) -> torch.Tensor:
    """Normalised dB under ``source``'s statistics -> the same dB under ``target``'s; masked cells stay 0."""
    db = radar.double() * source.db_std + source.db_mean
    out = ((db - target.db_mean) / target.db_std).to(radar.dtype)
    return torch.where(mask[..., None], out, torch.zeros_like(out))


def check_same_grid(data: RadarSpec, model: RadarSpec, ckpt: str) -> None:
    """Refuse test data whose radar grid or dB floor is not the one the model was trained on."""
    a, b = data.to_dict(), model.to_dict()
    def same(x, y) -> bool:
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return x.shape == y.shape and np.allclose(x, y, rtol=1e-9, atol=0)

    differ = [key for key in ("aspect_rad", "roll_rad", "freq_hz", "size_m", "roll_symmetric", "floor_db")
              if not same(a[key], b[key])]
    if differ:
        raise UserInputError(f"model.init_args.ckpt: {ckpt} was trained on radar {model.describe()}; the test data "
                             f"has {data.describe()} (differs in {', '.join(differ)})")


class CheckpointModel(ReconstructionModel):
    """Reconstructions of a trained RadarDiffusion or profile model checkpoint, unchanged.

    Args:
        ckpt: checkpoint path, ``"default"`` for the default shipped model, or a shipped model's name
            (:data:`radar2shape.pretrained.SHIPPED_MODELS`).
        num_samples: K sampled shapes averaged per reconstruction (None: the checkpoint's own).
        surface_level: the decoded SDF level meshed as the surface (None: the checkpoint's own;
            latent models only): how a level is tried on the validation split before it is exported.
        mesh_resolution: marching-cubes grid of the reconstructions and the Stage-1 ceiling (None:
            the checkpoint's own; latent models only).
        verifier: a verifier file (:mod:`radar2shape.models.verifier`), or ``"beside"`` for the
            checkpoint's own ``<name>.verifier.pt``: each reconstruction is then the mean SDF of the
            ``keep`` best-scored of ``candidates`` samples, as ``reconstruct --candidates`` returns it,
            and carries their mean predicted IoU (logged per shape beside the true IoU).
        candidates, keep: K samples drawn and how many of the best-scored are averaged (with ``verifier``).
    """

    def __init__(self, ckpt: str = DEFAULT, num_samples: int | None = None, surface_level: float | None = None,
                 mesh_resolution: int | None = None, verifier: str | None = None, candidates: int = 8,
                 keep: int = 3) -> None:
        super().__init__()
        self.save_hyperparameters()
        from radar2shape.pretrained import DEFAULT_NAME, SHIPPED_MODELS, load_model, shipped_checkpoint

        if num_samples is not None and num_samples < 1:
            raise UserInputError(f"model.init_args.num_samples: expected a positive count, got {num_samples}")
        name = DEFAULT_NAME if ckpt == DEFAULT else ckpt
        self.ckpt_path = str(shipped_checkpoint(name) if name in SHIPPED_MODELS else ckpt)
        # In a fresh context, as RadarDiffusion loads its Stage 1: the Lightning CLI builds this class
        # inside a context that would hand our hyperparameters to the loaded model too.
        inner = contextvars.Context().run(load_model, self.ckpt_path, "model.init_args.ckpt")
        if num_samples is not None:
            inner.hparams.num_samples = int(num_samples)
        for option, value in (("surface_level", surface_level), ("mesh_resolution", mesh_resolution)):
            if value is not None and getattr(inner, "stage1", None) is None:
                raise UserInputError(f"model.init_args.{option}: {self.ckpt_path} is a {type(inner).__name__}, "
                                     "which meshes no latent SDF; only Radar2Shape (RadarDiffusion) checkpoints take it")
        if mesh_resolution is not None and mesh_resolution < 2:
            raise UserInputError(f"model.init_args.mesh_resolution: expected an integer >= 2, got {mesh_resolution}")
        if surface_level is not None:
            inner.stage1.hparams.surface_level = float(surface_level)
        if mesh_resolution is not None:
            inner.hparams.mesh_resolution = int(mesh_resolution)
        self.inner = inner.requires_grad_(False)
        self.verifier = None if verifier is None else self._load_verifier(verifier, candidates, keep)
        self._data_spec: RadarSpec | None = None

    def _load_verifier(self, verifier: str, candidates: int, keep: int):
        from pathlib import Path

        from radar2shape.models.verifier import default_verifier_path, load_verifier

        if getattr(self.inner, "stage1", None) is None:
            raise UserInputError(f"model.init_args.verifier: {self.ckpt_path} is a {type(self.inner).__name__}; "
                                 "a verifier chooses among Radar2Shape (RadarDiffusion) samples")
        if not 1 <= keep <= candidates:
            raise UserInputError(f"model.init_args.keep: expected 1 to candidates ({candidates}), got {keep}")
        path = default_verifier_path(Path(self.ckpt_path)) if verifier == "beside" else Path(verifier)
        if not path.is_file():
            raise UserInputError(f"model.init_args.verifier: no verifier file {path} (scripts/train_verifier.py)")
        return load_verifier(path, self.inner.n_levels, candidates).requires_grad_(False)

    def setup(self, stage: str) -> None:
        if stage != "test":
            raise UserInputError("CheckpointModel scores a trained model as it is: run it with 'radar2shape test'")
        spec = getattr(self.trainer.datamodule, "radar_spec", None)
        if spec is None:
            raise UserInputError("CheckpointModel needs a DataModule with a radar_spec (data_modules.ShapeDataModule)")
        check_same_grid(spec, self.inner.radar_spec, self.ckpt_path)
        self._data_spec = spec

    def losses(self, batch: dict) -> dict[str, torch.Tensor]:
        """Nothing is trained; scores come from :meth:`reconstruct`."""
        return {}

    def _model_batch(self, batch: dict) -> dict:
        if self._data_spec is None:
            raise RuntimeError("CheckpointModel.setup('test') has not run (attach it to a Trainer)")
        radar = renormalise(batch["radar"], batch["radar_mask"], self._data_spec, self.inner.radar_spec)
        return {**batch, "radar": radar}

    @torch.no_grad()
    def reconstruct(self, batch: dict) -> list[Reconstruction]:
        batch = self._model_batch(batch)
        if self.verifier is None:
            return self.inner.reconstruct(batch)
        from radar2shape.models.verifier import verified_latents

        hp, out = self.hparams, []
        for i in range(len(batch["radar"])):
            one = {key: batch[key][i:i + 1] for key in ("radar", "radar_mask")}
            latents, predicted, kept = verified_latents(self.inner, self.verifier, one, hp.candidates, hp.keep)
            mesh, _ = self.inner.mean_mesh(latents[kept])
            out.append(Reconstruction(mesh=self.inner.place_in_heading(mesh, one, 0),
                                      predicted_iou=float(predicted[kept].mean())))
        return out

    @torch.no_grad()
    def reconstruct_ceiling(self, batch: dict) -> list[Reconstruction] | None:
        return self.inner.reconstruct_ceiling(self._model_batch(batch))
