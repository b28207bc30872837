"""DataModules: batch keys, masks, noise, determinism, statistics and errors."""

import gc

import lightning as L
import numpy as np
import pytest
import torch
from conftest import REPO
from jsonargparse import ArgumentParser

from data_modules import ProfileDataModule, ShapeDataModule
from data_modules.radar_transform import RadarTransform
from radar2shape.errors import UserInputError
from radar2shape.radar import RadarGrid
from radar2shape.radar.spec import RadarSpec

SMALL_POINTS = {"train": {"surface": 64, "sdf": 128}, "val": {"surface": 64, "sdf": 128, "eval": 100, "occ": 200},
                "test": {"surface": 64, "sdf": 128, "eval": 100, "occ": 200}}


def _module(root, cls=ShapeDataModule, **kwargs):
    return cls(str(root), batch_size=2, points=SMALL_POINTS, **kwargs)


def _windows(mask_1d: np.ndarray) -> int:
    """Number of contiguous True runs on a circle."""
    return int(np.sum(mask_1d & ~np.roll(mask_1d, 1))) if not mask_1d.all() else 1


def test_batches_hold_exactly_the_contract_keys(parts_dataset):
    dm = _module(parts_dataset)
    a, r, f = dm.radar_shape
    assert dm.num_classes == len(dm.class_names) == 10
    train = next(iter(dm.train_dataloader()))
    assert set(train) == {"radar", "radar_mask", "surface_points", "surface_normals", "sdf_points", "sdf_values",
                          "label", "index"}
    test = next(iter(dm.test_dataloader()))
    assert set(test) == set(train) | {"eval_points", "occ_points", "occ_inside"}
    expected = {"radar": ((2, a, r, f), torch.float32), "radar_mask": ((2, a, r), torch.bool),
                "surface_points": ((2, 64, 3), torch.float32), "surface_normals": ((2, 64, 3), torch.float32),
                "sdf_points": ((2, 128, 3), torch.float32), "sdf_values": ((2, 128), torch.float32),
                "eval_points": ((2, 100, 3), torch.float32), "occ_points": ((2, 200, 3), torch.float32),
                "occ_inside": ((2, 200), torch.bool), "label": ((2,), torch.int64), "index": ((2,), torch.int64)}
    for key, value in test.items():
        assert (tuple(value.shape), value.dtype) == expected[key], key
    assert (test["radar"][~test["radar_mask"]] == 0).all()


def test_partial_observability_masks_one_window_per_axis(parts_dataset):
    dm = _module(parts_dataset)
    a, r, _ = dm.radar_shape
    for split, check in (("train", lambda k: 0.3 - 1e-9 <= k <= 1.0), ("test", lambda k: abs(k - 0.3) <= 1.0 / 16 + 1e-9)):
        dataset = dm.dataset(split)
        for index in range(len(dataset)):
            mask = dataset[(0, index)]["radar_mask"].numpy()
            rows, cols = mask.any(axis=1), mask.any(axis=0)
            assert (mask == np.outer(rows, cols)).all()  # a window: product of one run per axis
            assert _windows(rows) == 1 and _windows(cols) == 1
            assert check(rows.mean()) and check(cols.mean()), (split, rows.mean(), cols.mean())
    full = _module(parts_dataset, observability="full").dataset("test")[0]
    assert full["radar_mask"].all()


def test_items_are_deterministic_and_fresh_each_epoch(parts_dataset):
    dataset = _module(parts_dataset).dataset("train")
    first, again, later = dataset[(0, 1)], dataset[(0, 1)], dataset[(1, 1)]
    for key in first:
        assert torch.equal(first[key], again[key])
    assert not torch.equal(first["sdf_points"], later["sdf_points"])
    test = _module(parts_dataset).dataset("test")
    assert torch.equal(test[(0, 0)]["radar"], test[(5, 0)]["radar"])


def test_batches_do_not_depend_on_the_number_of_workers(parts_dataset):
    batches = []
    for workers in (0, 2):
        dm = _module(parts_dataset, num_workers=workers, train_noise_db=(-80.0, -40.0))
        loader = dm.train_dataloader()
        loader.sampler.set_epoch(3)
        batches.append(list(loader))
        del loader  # stop the persistent workers now, not at some later garbage collection
        gc.collect()
    for one, two in zip(*batches):
        for key in one:
            assert torch.equal(one[key], two[key]), key


@pytest.mark.parametrize("level", [-60.0, -40.0])
def test_noise_has_the_stated_power(level):
    spec = RadarSpec(RadarGrid(np.zeros(64), np.zeros(64), np.ones(64)), db_mean=0.0, db_std=1.0, floor_db=-400.0)
    transform = RadarTransform(spec, observability="full", noise_db=level)
    radar, _ = transform(np.zeros((64, 64, 64), np.complex64), np.random.default_rng(0), 0)
    power = np.mean(10.0 ** (radar.astype(np.float64) / 10.0))
    assert power == pytest.approx(10.0 ** (level / 10.0), rel=0.03)


def test_noise_is_added_before_the_db_conversion(parts_dataset):
    clean = _module(parts_dataset, observability="full").dataset("test")[0]["radar"]
    noisy = _module(parts_dataset, observability="full", test_noise_db=-20.0).dataset("test")[0]["radar"]
    assert not torch.equal(clean, noisy)


def test_statistics_for_another_floor_are_computed_once_and_cached(parts_dataset):
    dm = _module(parts_dataset, floor_db=-60.0)
    assert (parts_dataset / "radar_stats_floor-60.json").is_file()
    spec, default = dm.radar_spec, _module(parts_dataset).radar_spec
    assert spec.floor_db == -60.0 and default.floor_db == -100.0 and spec.db_mean > default.db_mean
    assert dm.transform("train").spec is spec


def test_train_records_give_raw_complex_radar(parts_dataset):
    records = _module(parts_dataset).train_records()
    assert len(records) == _module(parts_dataset).manifest["counts"]["train"]
    assert np.iscomplexobj(records[0]["radar"])


def test_profile_module_reduces_radar_to_aspect_by_frequency(frusta_dataset, parts_dataset):
    dm = _module(frusta_dataset, ProfileDataModule)
    a, f = dm.radar_shape
    batch = next(iter(dm.test_dataloader()))
    assert batch["radar"].shape == (2, a, f) and batch["radar_mask"].shape == (2, a)
    assert batch["profile"].shape == (2, dm.profile_points, 2) and batch["profile"].dtype == torch.float32
    assert (batch["radar"][~batch["radar_mask"]] == 0).all()
    assert _windows(batch["radar_mask"][0].numpy()) == 1
    with pytest.raises(UserInputError, match="no profiles"):
        _module(parts_dataset, ProfileDataModule)


def test_missing_dataset_names_the_path_and_the_fix(tmp_path):
    with pytest.raises(UserInputError, match=r"nowhere.*make data"):
        ShapeDataModule(str(tmp_path / "nowhere"))
    (tmp_path / "half").mkdir()
    with pytest.raises(UserInputError, match=r"manifest.json not found.*resumes"):
        ShapeDataModule(str(tmp_path / "half"))


def test_lightning_cli_data_configs_parse():
    for path in sorted((REPO / "conf/data/module").glob("*.yaml")):
        parser = ArgumentParser()
        parser.add_subclass_arguments(L.LightningDataModule, "data")
        assert parser.parse_args([f"--data={path}"]).data.class_path.startswith("data_modules.")


def test_radar_spec_is_the_manifest_grid_and_train_statistics(parts_dataset, frusta_dataset):
    dm = _module(parts_dataset, observability="full")
    spec, manifest = dm.radar_spec, dm.manifest
    np.testing.assert_array_equal(spec.grid.freq_hz, manifest["radar"]["freq_hz"])
    assert spec.grid.shape == dm.radar_shape == (16, 16, 16) and not spec.roll_symmetric
    assert (spec.db_mean, spec.db_std, spec.floor_db) == (manifest["radar_stats"]["mean"],
                                                         manifest["radar_stats"]["std"], -100.0)
    # the batch radar is exactly the spec's normalisation of the stored response
    raw = dm.records("test")[0]["radar"]
    np.testing.assert_array_equal(dm.dataset("test")[0]["radar"].numpy(), spec.normalise(spec.to_db(raw)))
    profile = _module(frusta_dataset, ProfileDataModule).radar_spec
    assert profile.roll_symmetric and profile.grid.roll_rad.tolist() == [0.0] and profile.input_shape == (16, 16)


def test_cells_rule_masks_the_requested_fraction_of_cells(parts_dataset):
    dm = _module(parts_dataset, mask_rule="cells")
    a, r, _ = dm.radar_shape
    assert (a, r) == (16, 16)
    for index in range(len(dm.dataset("test"))):  # 0.3 * 256 = 76.8 cells -> 77 = 7 x 11 (70 % masked)
        mask = dm.dataset("test")[index]["radar_mask"].numpy()
        rows, cols = mask.any(axis=1), mask.any(axis=0)
        assert (mask == np.outer(rows, cols)).all() and _windows(rows) == 1 and _windows(cols) == 1
        assert mask.sum() == 77 and {rows.sum(), cols.sum()} == {7, 11}
    train = dm.dataset("train")
    for epoch in range(3):
        mask = train[(epoch, 0)]["radar_mask"].numpy()
        assert 77 <= mask.sum() <= 256 and _windows(mask.any(axis=0)) == 1
    per_axis = _module(parts_dataset).dataset("test")[0]["radar_mask"].numpy()
    assert per_axis.sum() == 25  # round(0.3 * 16) = 5 per axis: ~10 % of the cells


def test_peak_relative_noise_has_the_stated_power_below_the_peak():
    spec = RadarSpec(RadarGrid(np.zeros(64), np.zeros(64), np.ones(64)), db_mean=0.0, db_std=1.0, floor_db=-400.0)
    transform = RadarTransform(spec, observability="full", noise_db=-40.0, noise_reference="peak")
    response = np.zeros((64, 64, 64), np.complex64)
    response[3, 4, 5] = 100.0  # peak power 1e4 m^2 -> noise 1 m^2 everywhere
    radar, _ = transform(response, np.random.default_rng(0), 0)
    power = np.mean(np.delete(10.0 ** (radar.astype(np.float64).ravel() / 10.0), 3 * 64 * 64 + 4 * 64 + 5))
    assert power == pytest.approx(1.0, rel=0.03)  # 262,143 exponential draws: s.e. 0.2 %


def test_peak_noise_option_reaches_the_batches(parts_dataset, frusta_dataset):
    absolute = _module(parts_dataset, observability="full", test_noise_db=-20.0).dataset("test")[0]["radar"]
    peak = _module(parts_dataset, observability="full", test_noise_db=-20.0, noise_reference="peak")
    assert peak.transform("test").noise_reference == "peak"
    assert not torch.equal(absolute, peak.dataset("test")[0]["radar"])
    profile = _module(frusta_dataset, ProfileDataModule, mask_rule="cells", noise_reference="peak",
                      test_noise_db=-10.0)
    assert profile.dataset("test")[0]["radar_mask"].sum() == 5  # 0.3 * 16 aspects = 4.8 -> 5


@pytest.mark.parametrize("option, match", [
    ({"mask_rule": "square"}, "mask_rule: expected one of per_axis, cells"),
    ({"noise_reference": "mean"}, "noise_reference: expected one of absolute, peak"),
    ({"test_keep": 0.0}, "test_keep: expected a kept fraction"),
    ({"train_keep": [0.8, 0.3]}, "train_keep: expected a kept fraction"),
    ({"observability": "half"}, "observability: expected 'full' or 'partial'"),
    ({"test_split": "train"}, "test_split: expected 'val' or 'test', got 'train'"),
])
def test_bad_observability_and_noise_options_name_the_option(parts_dataset, option, match):
    with pytest.raises(UserInputError, match=match):
        _module(parts_dataset, **option)


def test_test_split_val_scores_the_validation_records(parts_dataset):
    """``test_split='val'``: ``radar2shape test`` reads the validation records, with the test points and mask."""
    fewer = {**SMALL_POINTS, "val": {"surface": 32, "sdf": 64, "eval": 50, "occ": 100}}
    on_val = ShapeDataModule(str(parts_dataset), batch_size=2, points=fewer, test_split="val")
    on_test = _module(parts_dataset)
    val_items = [item for batch in on_val.test_dataloader() for item in batch["index"].tolist()]
    assert len(val_items) == len(on_val.records("val")) != 0
    first_val = next(iter(_module(parts_dataset).val_dataloader()))  # the val records with the test's point counts
    first = next(iter(on_val.test_dataloader()))
    assert {k: v.shape for k, v in first.items()} == {k: v.shape for k, v in next(iter(on_test.test_dataloader())).items()}
    assert next(iter(on_val.val_dataloader()))["occ_points"].shape == (2, 100, 3)  # validation keeps its own
    torch.testing.assert_close(first["occ_inside"], first_val["occ_inside"])
    torch.testing.assert_close(first["radar"], first_val["radar"])


def test_cached_records_give_the_same_items_and_read_each_file_once(parts_dataset, tmp_path):
    """``cache_records``: items equal the uncached ones (masks, noise and point subsets included),
    and after one pass the files are no longer needed."""
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(parts_dataset, copy)
    options = dict(observability="partial", train_noise_db=-40.0)
    plain = _module(parts_dataset, **options).dataset("train")
    cached = _module(copy, cache_records=True, **options).dataset("train")
    keys = [(0, i) for i in range(len(plain))]
    first = [cached[k] for k in keys]
    shutil.rmtree(copy / "records")  # every later read must come from memory
    for key, item in zip(keys + [(1, 0), (1, 1)], first + [cached[(1, 0)], cached[(1, 1)]]):
        reference = plain[key]
        assert set(item) == set(reference)
        for name in item:
            torch.testing.assert_close(item[name], reference[name], rtol=0, atol=0)
    assert _module(parts_dataset).dataset("train").cache is None  # off by default


def test_roll_augment_turns_radar_and_points_together_exactly(parts_dataset):
    """An augmented train item is the plain item turned by the whole roll steps it names (``roll_turn``
    = shift + R * mirror): the radar re-indexed along roll, the points rotated by the matching angle,
    SDF values unchanged; val/test items are never turned."""
    plain = _module(parts_dataset, observability="full").dataset("train")
    turned = _module(parts_dataset, observability="full", roll_augment=True).dataset("train")
    count = len(plain.transform.spec.grid.roll_rad)
    step = 2 * np.pi / count
    seen = set()
    for epoch, index in [(e, i) for e in range(3) for i in range(len(plain))]:
        a, b = plain[(epoch, index)], turned[(epoch, index)]
        assert "roll_turn" not in a
        shift, mirror = int(b["roll_turn"]) % count, bool(int(b["roll_turn"]) // count)
        c, s = np.cos(shift * step), np.sin(shift * step)
        rotation = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.diag([1.0, -1.0 if mirror else 1.0, 1.0])
        for key in ("surface_points", "surface_normals", "sdf_points"):
            np.testing.assert_allclose(b[key].double().numpy(), a[key].double().numpy() @ rotation.T, atol=1e-5)
        order = np.roll((-np.arange(count)) % count if mirror else np.arange(count), shift)
        torch.testing.assert_close(b["radar"], a["radar"][:, order], rtol=0, atol=0)
        torch.testing.assert_close(b["sdf_values"], a["sdf_values"], rtol=0, atol=0)
        seen.add((shift, mirror))
    assert len(seen) > 5  # the draw varies over items and epochs
    val = _module(parts_dataset, observability="full", roll_augment=True).dataset("val")
    item = val[(0, 0)]
    assert "roll_turn" not in item
    torch.testing.assert_close(item["surface_points"], _module(parts_dataset).dataset("val")[(0, 0)]["surface_points"])


def test_roll_augment_step_turns_by_its_multiples_only(parts_dataset):
    """``roll_augment_step`` = R/4: every draw is a quarter turn (mirrored or not), all 8 of them occur,
    and the item is the plain one turned exactly that way; a step that does not divide R is refused."""
    plain = _module(parts_dataset, observability="full").dataset("train")
    count = len(plain.transform.spec.grid.roll_rad)
    quarter = _module(parts_dataset, observability="full", roll_augment=True, roll_augment_step=count // 4).dataset("train")
    seen = set()
    for epoch, index in [(e, i) for e in range(8) for i in range(len(plain))]:
        a, b = plain[(epoch, index)], quarter[(epoch, index)]
        shift, mirror = int(b["roll_turn"]) % count, bool(int(b["roll_turn"]) // count)
        assert shift % (count // 4) == 0
        angle = 2 * np.pi * shift / count
        rotation = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
        rotation = rotation @ np.diag([1.0, -1.0 if mirror else 1.0, 1.0])
        np.testing.assert_allclose(b["surface_points"].double().numpy(), a["surface_points"].double().numpy() @ rotation.T,
                                   atol=1e-5)
        seen.add((shift, mirror))
    assert len(seen) == 8
    for bad in (0, 3 if count % 3 else 5):
        with pytest.raises(UserInputError, match=f"roll_augment_step: expected a divisor of the {count} roll steps"):
            _module(parts_dataset, roll_augment=True, roll_augment_step=bad)


def test_roll_augment_skip_classes_leaves_those_classes_in_their_stored_heading(parts_dataset):
    """The named class's items are the plain ones with ``roll_turn`` 0 (so batches of both kinds
    collate); the other classes are still turned; an unknown class name is one error naming the field."""
    plain = _module(parts_dataset, observability="full")
    skipped_class = plain.class_names[plain.dataset("train").labels[0]]
    module = _module(parts_dataset, observability="full", roll_augment=True, roll_augment_skip_classes=[skipped_class])
    dataset, reference = module.dataset("train"), plain.dataset("train")
    turns = {True: set(), False: set()}
    for epoch, index in [(e, i) for e in range(3) for i in range(len(dataset))]:
        item = dataset[(epoch, index)]
        skipped = plain.class_names[dataset.labels[index]] == skipped_class
        turns[skipped].add(int(item["roll_turn"]))
        if skipped:
            torch.testing.assert_close(item["surface_points"], reference[(epoch, index)]["surface_points"], rtol=0, atol=0)
            torch.testing.assert_close(item["radar"], reference[(epoch, index)]["radar"], rtol=0, atol=0)
    assert turns[True] == {0} and len(turns[False]) > 3
    assert "roll_turn" in next(iter(module.train_dataloader()))
    with pytest.raises(UserInputError, match=r"roll_augment_skip_classes: unknown class\(es\) \['zeppelin'\]"):
        _module(parts_dataset, roll_augment=True, roll_augment_skip_classes=["zeppelin"])


def test_unturned_train_loader_gives_every_record_in_its_stored_heading(parts_dataset):
    """For per-record caches: in order, no ``roll_turn``, the plain items' points, even with roll_augment;
    and the augmented training loader is still augmented after it."""
    module = _module(parts_dataset, observability="full", roll_augment=True)
    batches = list(module.unturned_train_dataloader())
    plain = _module(parts_dataset, observability="full").dataset("train")
    items = [item for batch in batches for item in (dict(zip(batch, v)) for v in zip(*batch.values()))]
    assert [int(item["index"]) for item in items] == list(range(len(plain)))
    for index, item in enumerate(items):
        assert "roll_turn" not in item
        torch.testing.assert_close(item["surface_points"], plain[(0, index)]["surface_points"], rtol=0, atol=0)
    assert "roll_turn" in next(iter(module.train_dataloader()))


def test_roll_augment_is_refused_for_roll_symmetric_data(frusta_dataset):
    with pytest.raises(UserInputError, match="roll_augment"):
        _module(frusta_dataset, cls=ProfileDataModule, roll_augment=True)
