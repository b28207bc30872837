"""Datasets over built records: raw access, and the training view with masks, noise and subsets.

Randomness is a pure function of ``(seed, split, epoch, index)``, so an item is the same in any
DataLoader worker, with any number of workers, and on every DDP rank; the epoch reaches the
dataset through the index itself (``EpochSampler`` yields ``(epoch, index)`` pairs) because
worker processes never see attributes set on the main-process dataset.

A damaged record (truncated, corrupt, missing) raises ``BadRecordError`` naming the file, or, with
``skip_bad=True``, is replaced by the next readable record in index order (the same substitute in
every worker and epoch), with ``record_skipped`` set in the item so the DataModule can count it.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset, Sampler

from data_modules.radar_transform import RadarTransform
from data_modules.records import read_record, record_path, verify_command
from radar2shape.errors import BadRecordError

POINT_KEYS = {  # subset name -> record keys sharing one index set
    "surface": ("surface_points", "surface_normals"),
    "sdf": ("sdf_points", "sdf_values"),
    "eval": ("eval_points",),
    "occ": ("occ_points", "occ_inside"),
}
_SPLIT_CODES = {"train": 0, "val": 1, "test": 2}
AUGMENT_STREAM = 7  # a fifth seed word: the roll augmentation's own generator


class RecordSet(Sequence):
    """Lazy read-only access to the raw records of one split (baselines, plots, statistics)."""

    def __init__(self, root: str | Path, split: str, record_ids: list[str], keys: Sequence[str] | None = None):
        self.root, self.split, self.record_ids = Path(root), split, list(record_ids)
        self.keys = None if keys is None else tuple(keys)

    def __len__(self) -> int:
        return len(self.record_ids)

    def path(self, index: int) -> Path:
        return record_path(self.root, self.split, self.record_ids[index])

    def __getitem__(self, index: int) -> dict:
        if not -len(self) <= index < len(self):
            raise IndexError(index)
        return read_record(self.path(index), self.keys)


class EpochSampler(Sampler):
    """Yields ``(epoch, index)``; shuffles with a generator seeded by ``(seed, epoch)``.

    Lightning calls ``set_epoch`` before each epoch; without it (plain loops, DDP wrappers) the
    epoch advances by one per pass, which gives the same sequence on every rank.
    """

    def __init__(self, length: int, shuffle: bool = True, seed: int = 0):
        self.length, self.shuffle, self.seed, self.epoch = length, shuffle, seed, 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def __len__(self) -> int:
        return self.length

    def __iter__(self) -> Iterator[tuple[int, int]]:
        epoch = self.epoch
        self.epoch += 1
        order = np.random.default_rng([self.seed, epoch]).permutation(self.length) if self.shuffle else range(self.length)
        return iter([(epoch, int(i)) for i in order])


class RecordDataset(Dataset):
    """Items with the batch keys of docs/design.md section 10 for the full 3D radar ``[A, R, F]``.

    ``points`` maps a subset name (surface, sdf, eval, occ) to a count: ``-1`` = all stored
    points, missing or 0 = leave the keys out; evaluation takes at most the stored count
    (training draws with replacement past it). Training draws a fresh random subset per epoch;
    evaluation takes the first points (records store them in random order), so it is fixed.
    """

    def __init__(self, records: RecordSet, labels: list[int], transform: RadarTransform, points: dict[str, int],
                 train: bool, seed: int = 0, cache: bool = False, skip_bad: bool = False, roll_augment: bool = False,
                 roll_augment_step: int = 1, unturned_labels: frozenset[int] = frozenset()):
        unknown = sorted(set(points) - set(POINT_KEYS))
        if unknown:
            raise ValueError(f"points: unknown subset(s) {unknown}; expected some of {sorted(POINT_KEYS)}")
        self.records, self.labels, self.transform = records, labels, transform
        self.points = {name: int(n) for name, n in points.items() if n}
        self.train, self.seed = train, seed
        self.keys = ["radar"] + [key for name in self.points for key in POINT_KEYS[name]] + self.extra_keys()
        self.cache: dict[int, dict] | None = {} if cache else None
        self.skip_bad = skip_bad
        self.roll_augment, self.roll_augment_step = roll_augment, int(roll_augment_step)
        self.unturned_labels = unturned_labels  # classes roll_augment leaves in their stored heading
        self._reported: set[int] = set()  # bad records already warned about in this process

    def read(self, index: int) -> dict:
        """The record's arrays for :attr:`keys`; kept in memory after the first read when caching
        (opening an ``.npz`` costs more than a small model's training step on it)."""
        if self.cache is None:
            return read_record(self.records.path(index), self.keys)
        if index not in self.cache:
            self.cache[index] = read_record(self.records.path(index), self.keys)
        return self.cache[index]

    def extra_keys(self) -> list[str]:
        return []

    def turned(self, record: dict, epoch: int, index: int) -> dict:
        """``record`` turned by a random multiple of ``roll_augment_step`` roll steps and maybe mirrored (exact).

        The draw has its own generator, so the mask, noise and point subsets of the item are the
        ones it would have without the augmentation. The item carries the turn as ``roll_turn``
        (``shift + R * mirror``), so a model caching per-record quantities knows they do not apply.
        """
        from data_modules.augment import turn_and_mirror

        roll = self.transform.spec.grid.roll_rad
        draw = np.random.default_rng([*self.seed_words(epoch, index), AUGMENT_STREAM])
        step = self.roll_augment_step
        shift, mirror = step * int(draw.integers(len(roll) // step)), bool(draw.integers(2))
        return {**turn_and_mirror(record, shift, mirror, roll_rad=roll), "roll_turn": np.int64(shift + len(roll) * mirror)}

    def __len__(self) -> int:
        return len(self.records)

    def seed_words(self, epoch: int, index: int) -> list[int]:
        """What an item's randomness is a function of: seed, split, epoch (training only), index."""
        return [self.seed, _SPLIT_CODES.get(self.records.split, 3), epoch if self.train else 0, index]

    def rng(self, epoch: int, index: int) -> np.random.Generator:
        return np.random.default_rng(self.seed_words(epoch, index))

    def _subset(self, size: int, n: int, rng: np.random.Generator) -> slice | np.ndarray:
        if n < 0:
            return slice(None)
        if self.train:
            return rng.choice(size, n, replace=n > size)
        return slice(0, n)  # at most the stored count (every record of a dataset stores the same)

    def radar(self, response: np.ndarray, rng: np.random.Generator, index: int) -> tuple[np.ndarray, np.ndarray]:
        return self.transform(response, rng, index)

    def __getitem__(self, key: int | tuple[int, int]) -> dict[str, torch.Tensor]:
        epoch, index = key if isinstance(key, tuple) else (0, key)
        if not self.skip_bad:
            return self.item(epoch, index)
        for step in range(len(self)):
            candidate = (index + step) % len(self)
            try:
                item = self.item(epoch, candidate)
            except BadRecordError as err:
                if candidate not in self._reported:
                    self._reported.add(candidate)
                    print(f"warning: skipping a damaged record (data.skip_bad_records): {err}", file=sys.stderr)
                continue
            item["record_skipped"] = torch.tensor(step > 0)
            return item
        raise BadRecordError(f"{self.records.root}: every record of split {self.records.split!r} is damaged; "
                             f"check with '{verify_command(self.records.path(0))}'")

    def item(self, epoch: int, index: int) -> dict[str, torch.Tensor]:
        """The item of record ``index`` in ``epoch`` (no substitution)."""
        rng = self.rng(epoch, index)
        record = self.read(index)
        if self.roll_augment:  # a skipped class says it is unturned, so batches collate
            unturned = self.labels[index] in self.unturned_labels
            record = {**record, "roll_turn": np.int64(0)} if unturned else self.turned(record, epoch, index)
        radar, mask = self.radar(record["radar"], rng, index)
        item = {"radar": radar, "radar_mask": mask,
                "label": np.int64(self.labels[index]), "index": np.int64(index)}
        for name, n in self.points.items():
            first = record[POINT_KEYS[name][0]]
            chosen = self._subset(len(first), n, rng)
            for record_key in POINT_KEYS[name]:
                item[record_key] = record[record_key][chosen]
        if "occ_points" in item:
            item["occ_points"] = item["occ_points"].astype(np.float32)
        for extra in self.extra_keys():
            item[extra] = record[extra]
        if "roll_turn" in record:
            item["roll_turn"] = record["roll_turn"]
        return {k: torch.from_numpy(np.ascontiguousarray(v)) if isinstance(v, np.ndarray) else torch.tensor(v)
                for k, v in item.items()}


class ProfileDataset(RecordDataset):
    """Roll-symmetric view: radar ``[A, F]`` at roll 0, aspect-only mask ``[A]``, and the profile."""

    def extra_keys(self) -> list[str]:
        return ["profile"]

    def radar(self, response, rng, index):
        radar, mask = self.transform(response[:, :1], rng, index)
        return radar[:, 0], mask[:, 0]
