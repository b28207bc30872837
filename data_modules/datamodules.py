"""LightningDataModules over built datasets: ``ShapeDataModule`` (3D) and ``ProfileDataModule``.

Both read the manifest at construction, so ``class_names``, ``num_classes``, ``radar_shape`` and
``radar_spec`` (grid + dB normalisation, which the model stores in its checkpoints) are known
before a model is built (LightningCLI can link them). Options (see docs/data.md):
observability and noise per split, dB floor, point subset sizes per split.

A damaged record stops a run with one line naming the file and ``radar2shape build-data --verify``;
with ``skip_bad_records`` it is replaced deterministically and the skips are logged per epoch
(``<split>/skipped_records``, plus a warning line when any).
"""

from __future__ import annotations

import copy

import sys
from collections import Counter
from pathlib import Path

from lightning.pytorch.callbacks import Callback
from torch.utils.data import DataLoader

from data_modules.datasets import EpochSampler, ProfileDataset, RecordDataset, RecordSet
from data_modules.manifest import dataset_radar_spec, read_manifest
from data_modules.radar_transform import RadarTransform
from radar2shape.datamodule import ReconstructionDataModule
from radar2shape.errors import UserInputError
from radar2shape.radar.spec import RadarSpec

DEFAULT_POINTS = {
    "train": {"surface": 2048, "sdf": 8192},
    "val": {"surface": 2048, "sdf": 8192, "eval": 30000, "occ": 100000},
    "test": {"surface": 2048, "sdf": 8192, "eval": 30000, "occ": 100000},
}


def _keep_range(name: str, value) -> tuple[float, float]:
    """``value`` as a ``(low, high)`` kept-fraction range; one clear line naming ``name`` otherwise."""
    pair = (value, value) if isinstance(value, (int, float)) else value
    pair = tuple(pair) if isinstance(pair, (list, tuple)) else ()
    if len(pair) != 2 or not all(isinstance(v, (int, float)) for v in pair) or not 0 < pair[0] <= pair[1] <= 1:
        raise UserInputError(f"{name}: expected a kept fraction in (0, 1] or a [low, high] range of them, "
                             f"got {value!r}")
    return float(pair[0]), float(pair[1])


class ShapeDataModule(ReconstructionDataModule):
    """Batches of 3D radar ``[B, A, R, F]`` with shape targets (docs/design.md section 10, batch keys).

    Args:
        root: dataset folder written by ``radar2shape build-data``.
        observability: "partial" (train: random windows keeping a fraction in ``train_keep``;
            val/test: a window keeping ``test_keep``, placed by ``seed + index``) or "full".
        mask_rule: what the kept fraction is of: "per_axis" (of each axis, so ``test_keep=0.3``
            observes ~9 % of the cells) or "cells" (of the (aspect, roll) cells, the paper's rule:
            ``test_keep=0.3`` masks 70 % of the signal). Aspect-only data: the same under both.
        train_noise_db: None, a level in dB, or a ``[low, high]`` range drawn per sample.
        test_noise_db: None or a level in dB (val and test).
        noise_reference: "absolute" (levels in dBsm) or "peak" (dB relative to each response's peak
            |S|^2), for both splits.
        points: per split, subset sizes of surface/sdf/eval/occ points (-1 all, 0 none);
            merged over ``DEFAULT_POINTS``.
        cache_records: keep each record's arrays in memory after the first read (per loader
            process; workers are persistent). For datasets that fit in RAM: a small model's
            epoch is otherwise mostly spent opening ``.npz`` files.
        skip_bad_records: replace a damaged record (truncated, corrupt, missing) by the next
            readable one instead of stopping, and log the count per epoch; off by default, so a
            damaged dataset is noticed (``radar2shape build-data --verify/--repair`` fixes it).
        roll_augment: turn each training sample about z by a random whole number of roll steps and
            mirror it with probability 1/2 (``data_modules.augment``): exact, since the response
            only moves along roll, so one record gives 2R samples (the 3D data only).
        roll_augment_step: turn by multiples of this many roll steps only (it must divide R): R/4
            gives the 8 poses that keep the object's axes on the Stage-1 planes (quarter turns and
            the mirror), which long thin objects need (docs/sdf_vae.md).
        roll_augment_skip_classes: class names whose training samples ``roll_augment`` leaves in their
            stored heading: classes whose files share a front (every aircraft's nose along +x), for a
            Stage 1 that draws them in that frame only (docs/radar_diffusion.md, "Objects in any heading").
        test_split: the split ``radar2shape test`` scores, with the test split's points ("val" chooses
            a decoding setting, such as a surface level, without looking at the test split).
    """

    dataset_class = RecordDataset
    roll_symmetric = False

    def __init__(self, root: str = "data/parts", batch_size: int = 16, num_workers: int = 0, seed: int = 0,
                 floor_db: float = -100.0, observability: str = "partial",
                 train_keep: tuple[float, float] = (0.3, 1.0), test_keep: float = 0.3,
                 train_noise_db: float | tuple[float, float] | None = None, test_noise_db: float | None = None,
                 points: dict[str, dict[str, int]] | None = None, pin_memory: bool = False,
                 mask_rule: str = "per_axis", noise_reference: str = "absolute", cache_records: bool = False,
                 skip_bad_records: bool = False, roll_augment: bool = False, roll_augment_step: int = 1,
                 roll_augment_skip_classes: list[str] | None = None, test_split: str = "test"):
        super().__init__()
        self.save_hyperparameters()
        self.root = Path(root)
        self.manifest = read_manifest(self.root)
        self.class_names: list[str] = list(self.manifest["classes"])
        self.num_classes = len(self.class_names)
        self.points = {split: {**DEFAULT_POINTS[split], **((points or {}).get(split) or {})} for split in DEFAULT_POINTS}
        self._spec = dataset_radar_spec(self.root, self.manifest, float(floor_db), self.roll_symmetric)
        self.datasets: dict[tuple[str, str], RecordDataset] = {}  # (split, split whose points it samples)
        self.skipped: Counter = Counter()  # substituted items per split since the last epoch report
        _keep_range("test_keep", test_keep)  # train_keep: checked by transform("train")
        if test_split not in ("val", "test"):
            raise UserInputError(f"test_split: expected 'val' or 'test', got {test_split!r}")
        if roll_augment and self.roll_symmetric:
            raise UserInputError("roll_augment: roll-symmetric data has one roll angle; turning it changes nothing")
        roll_count = len(self.radar_spec.grid.roll_rad)
        if roll_augment_step < 1 or (not self.roll_symmetric and roll_count % roll_augment_step):
            raise UserInputError(f"roll_augment_step: expected a divisor of the {roll_count} roll steps, got {roll_augment_step}")
        self.unturned_labels = frozenset(self.labels_of("roll_augment_skip_classes", roll_augment_skip_classes or []))
        for split in ("train", "test"):
            self.transform(split)  # bad observability, mask or noise options fail here, not mid-epoch

    def labels_of(self, field: str, names: list[str]) -> list[int]:
        """The label of each class name in ``names`` (an option ``field``); an unknown name is one error."""
        unknown = [name for name in names if name not in self.class_names]
        if unknown:
            raise UserInputError(f"{field}: unknown class(es) {unknown}; the data's classes are {self.class_names}")
        return [self.class_names.index(name) for name in names]

    @property
    def radar_spec(self) -> RadarSpec:
        """The radar grid and train dB statistics at ``floor_db`` (aspect-only at roll 0 for profiles)."""
        return self._spec

    @property
    def radar_shape(self) -> tuple[int, ...]:
        """Shape of one radar input: ``(A, R, F)`` (``(A, F)`` for roll-symmetric data)."""
        return self.radar_spec.input_shape

    def records(self, split: str) -> RecordSet:
        """Raw records of ``split`` (lazy)."""
        if split not in self.manifest["splits"]:
            raise UserInputError(f"{self.root}: no split {split!r} (has {sorted(self.manifest['splits'])})")
        return RecordSet(self.root, split, self.manifest["splits"][split])

    def train_records(self) -> RecordSet:
        """Raw train records, e.g. for nearest-neighbour baselines (``record["radar"]`` is complex)."""
        return self.records("train")

    def transform(self, split: str) -> RadarTransform:
        hp = self.hparams
        train = split == "train"
        return RadarTransform(
            spec=self.radar_spec, observability=hp.observability,
            keep=_keep_range("train_keep", hp.train_keep) if train else hp.test_keep,
            noise_db=hp.train_noise_db if train else hp.test_noise_db, mask_seed=hp.seed,
            mask_rule=hp.mask_rule, noise_reference=hp.noise_reference,
        )

    def dataset(self, split: str, points: str | None = None) -> RecordDataset:
        """The dataset of ``split`` (built on first use), with the point subsets of split ``points``
        (default: its own; the test split's when the test loader serves validation records)."""
        points = points or split
        if (split, points) not in self.datasets:
            records = self.records(split)
            if len(records) == 0:
                raise UserInputError(f"{self.root}: split {split!r} has no records")
            self.datasets[split, points] = self.dataset_class(
                records, self.manifest["labels"][split], self.transform(split), self.points[points],
                train=split == "train", seed=self.hparams.seed, cache=self.hparams.cache_records,
                skip_bad=self.hparams.skip_bad_records, roll_augment=self.hparams.roll_augment and split == "train",
                roll_augment_step=self.hparams.roll_augment_step, unturned_labels=self.unturned_labels,
            )
        return self.datasets[split, points]

    def _loader(self, split: str, points: str | None = None) -> DataLoader:
        dataset = self.dataset(split, points)
        workers = self.hparams.num_workers
        return DataLoader(
            dataset, batch_size=self.hparams.batch_size, num_workers=workers,
            sampler=EpochSampler(len(dataset), shuffle=split == "train", seed=self.hparams.seed),
            persistent_workers=workers > 0, pin_memory=self.hparams.pin_memory,
        )

    def setup(self, stage: str) -> None:
        """With ``skip_bad_records``, attach the callback that logs the skips at each epoch end."""
        trainer = getattr(self, "trainer", None)
        if self.hparams.skip_bad_records and trainer is not None and \
                not any(isinstance(c, SkippedRecordsLogger) for c in trainer.callbacks):
            trainer.callbacks.append(SkippedRecordsLogger(self))

    def on_before_batch_transfer(self, batch, dataloader_idx: int):
        """Count (and drop) the ``record_skipped`` flags of a batch: models never see the key."""
        flags = batch.pop("record_skipped", None) if isinstance(batch, dict) else None
        trainer = getattr(self, "trainer", None)
        if flags is not None and trainer is not None and not trainer.sanity_checking:
            self.skipped[_split_of(trainer)] += int(flags.sum())
        return batch

    def train_dataloader(self) -> DataLoader:
        return self._loader("train")

    def val_dataloader(self) -> DataLoader:
        return self._loader("val")

    def unturned_train_dataloader(self) -> DataLoader:
        """The training records in order, each in its stored (canonical) heading, whatever ``roll_augment``
        says: for quantities kept per record, such as a Stage-1 latent cache."""
        dataset = self.dataset("train")
        if dataset.roll_augment:
            dataset = copy.copy(dataset)
            dataset.roll_augment = False
        return DataLoader(dataset, batch_size=self.hparams.batch_size, num_workers=0,
                          sampler=EpochSampler(len(dataset), shuffle=False, seed=self.hparams.seed))

    def test_dataloader(self) -> DataLoader:
        return self._loader(self.hparams.test_split, "test")

    def predict_dataloader(self) -> DataLoader:
        return self._loader("test")


class ProfileDataModule(ShapeDataModule):
    """Roll-symmetric batches: radar ``[B, A, F]`` at roll 0, mask ``[B, A]``, ``profile [B, P, 2]``."""

    dataset_class = ProfileDataset
    roll_symmetric = True

    def __init__(self, root: str = "data/frusta", **kwargs):
        super().__init__(root, **kwargs)
        if self.manifest.get("profile_points") is None:
            raise UserInputError(f"{self.root}: records have no profiles (family {self.manifest['family']!r}); "
                                 "ProfileDataModule needs a roll-symmetric family such as frusta")
        self.profile_points: int = self.manifest["profile_points"]


def _split_of(trainer) -> str:
    if trainer.training:
        return "train"
    return "val" if trainer.validating else "test"


class SkippedRecordsLogger(Callback):
    """Logs ``<split>/skipped_records`` at each epoch end (summed over processes) and prints one
    warning line when records were substituted; added by the DataModule with ``skip_bad_records``."""

    def __init__(self, datamodule: ShapeDataModule):
        self.datamodule = datamodule

    def _report(self, trainer, pl_module, split: str) -> None:
        count = self.datamodule.skipped.pop(split, 0)
        pl_module.log(f"{split}/skipped_records", float(count), reduce_fx="sum", sync_dist=True)
        if count and trainer.is_global_zero:
            print(f"warning: epoch {trainer.current_epoch}: {count} {split} item(s) came from a substitute for a "
                  f"damaged record (data.skip_bad_records); check with 'radar2shape build-data --verify "
                  f"{self.datamodule.root}'", file=sys.stderr)

    def on_train_epoch_end(self, trainer, pl_module) -> None:
        self._report(trainer, pl_module, "train")

    def on_validation_epoch_end(self, trainer, pl_module) -> None:
        if not trainer.sanity_checking:
            self._report(trainer, pl_module, "val")

    def on_test_epoch_end(self, trainer, pl_module) -> None:
        self._report(trainer, pl_module, "test")
