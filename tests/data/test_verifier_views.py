"""scripts/train_verifier.py's extra views: a record turned by a seeded whole number of roll steps (and
maybe mirrored), radar and points together, as the exact symmetry augmentation turns it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import torch

from data_modules import ShapeDataModule
from data_modules.augment import turn_and_mirror

REPO = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("train_verifier", REPO / "scripts" / "train_verifier.py")
train_verifier = importlib.util.module_from_spec(spec)
spec.loader.exec_module(train_verifier)
KEYS = ("radar", "radar_mask", "occ_points", "eval_points")


def test_views_are_the_stored_record_and_seeded_exact_turns(parts_dataset):
    points = {"surface": 0, "sdf": 0, "eval": 300, "occ": 1000}
    dm = ShapeDataModule(root=str(parts_dataset), observability="full", points={"train": points})
    stored = dm.dataset("train")[(0, 2)]
    assert all(torch.equal(train_verifier.view_of(dm, "train", 2, 0)[k], stored[k]) for k in KEYS)
    roll = dm.radar_spec.grid.roll_rad
    arrays = {k: stored[k].numpy() for k in KEYS}
    found = []
    for view in (1, 2, 3, 4):
        turned = train_verifier.view_of(dm, "train", 2, view)
        assert torch.equal(turned["occ_inside"], stored["occ_inside"])  # labels travel with their points
        # the view is exactly one of the 2R whole-step turns (with or without the mirror) of the stored record
        matches = [(shift, mirror) for shift in range(len(roll)) for mirror in (False, True)
                   if all(np.array_equal(turned[k].numpy(), turn_and_mirror(arrays, shift, mirror, roll_rad=roll)[k])
                          for k in KEYS)]
        assert len(matches) >= 1
        again = train_verifier.view_of(dm, "train", 2, view)
        assert all(torch.equal(again[k], turned[k]) for k in KEYS)  # seeded by (record, view): repeatable
        found.append(matches[0])
    assert len(set(found)) > 1  # the views are not all the same turn


def test_fit_shapes_fill_from_each_folder_in_turn():
    keys = train_verifier.fit_keys_of([("a", 2), ("b", 3)], "train", fit_shapes=4, turns=2)
    # all of a's free records first, then b's first two; each record in its two views
    assert keys == [(source, "train", i, view) for source, i in (("a", 0), ("a", 1), ("b", 0), ("b", 1))
                    for view in (0, 1)]
    assert train_verifier.fit_keys_of([("a", 2), ("b", 3)], "train", fit_shapes=1, turns=1) == [("a", "train", 0, 0)]


def test_too_few_fit_records_is_one_error_line():
    with pytest.raises(SystemExit, match=r"--fit-shapes 6: only 5 train records free to fit in a \(2\), b \(3\)"):
        train_verifier.fit_keys_of([("a", 2), ("b", 3)], "train", fit_shapes=6, turns=1)


def test_a_cache_whose_keys_name_no_folder_belongs_to_the_first():
    store = {("train", 3, 0): "old", ("b", "train", 3, 0): "new"}
    assert train_verifier.upgrade_keys(store, "a") == {("a", "train", 3, 0): "old", ("b", "train", 3, 0): "new"}
