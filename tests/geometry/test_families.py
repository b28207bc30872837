"""Procedural families: watertight, deterministic, normalisable; SDF samples agree with containment."""

import numpy as np
import pytest
from winding_reference import winding_number

from radar2shape.geometry.families import PART_CLASSES, make_family
from radar2shape.geometry.normalise import normalise
from radar2shape.geometry.sampling import SamplingConfig, sample_shape

SPLITS = {"train": 0.6, "val": 0.2, "test": 0.2}
FAMILIES = {"frusta": {}, "parts": {}}


@pytest.mark.parametrize("name", FAMILIES)
def test_every_shape_is_a_single_watertight_solid(name):
    family = make_family(name, FAMILIES[name])
    for task in family.plan(3 * len(family.class_names), SPLITS, seed=1):
        mesh = family.generate(task).mesh
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0, task
        assert len(mesh.split(only_watertight=False)) == 1, task


def test_parts_has_ten_classes_with_structural_variants():
    family = make_family("parts")
    assert family.class_names == sorted(PART_CLASSES) and len(family.class_names) >= 8
    variants = {}
    for task in family.plan(100, {"train": 1.0}, seed=0):
        variants.setdefault(task.class_name, set()).add(str(family.generate(task).provenance["variant"]))
    assert all(len(v) >= 3 for v in variants.values()), {k: len(v) for k, v in variants.items()}


@pytest.mark.parametrize("name", FAMILIES)
def test_generation_is_deterministic_per_seed(name):
    family = make_family(name)
    tasks = family.plan(4, {"train": 1.0}, seed=7)
    again = make_family(name).plan(4, {"train": 1.0}, seed=7)
    assert tasks == again
    for task in tasks:
        np.testing.assert_array_equal(family.generate(task).mesh.vertices, family.generate(task).mesh.vertices)
    assert len({t.seed for t in family.plan(50, SPLITS, seed=7)}) == 50


def test_plan_balances_classes_and_splits():
    tasks = make_family("parts").plan(100, SPLITS, seed=0)
    assert [sum(t.split == s for t in tasks) for s in SPLITS] == [60, 20, 20]
    counts = np.bincount([t.label for t in tasks if t.split == "train"])
    assert counts.max() - counts.min() <= 1


@pytest.mark.parametrize("name", FAMILIES)
def test_normalisation_round_trips(name):
    family = make_family(name)
    for task in family.plan(3, {"train": 1.0}, seed=2):
        mesh = family.generate(task).mesh
        unit, centre, scale = normalise(mesh)
        lo, hi = unit.bounds
        np.testing.assert_allclose(lo + hi, 0.0, atol=1e-12)
        assert (hi - lo).max() == pytest.approx(1.0)
        np.testing.assert_allclose(unit.vertices / scale + centre, mesh.vertices, atol=1e-12)


@pytest.mark.parametrize("name", FAMILIES)
def test_sdf_signs_agree_with_winding_number(name):
    family = make_family(name)
    config = SamplingConfig(surface=100, eval=100, sdf=1500, occ=500)
    for task in family.plan(2, {"train": 1.0}, seed=3):
        mesh, _, _ = normalise(family.generate(task).mesh)
        sample = sample_shape(mesh, config, seed=task.seed)
        for points, inside in ((sample["sdf_points"], sample["sdf_values"] < 0),
                               (sample["occ_points"], sample["occ_inside"])):
            reference = winding_number(mesh.vertices, mesh.faces, points.astype(np.float64)) > 0.5
            assert (reference == inside).mean() > 0.995
        near = int(round(config.sdf * config.sdf_near_fraction))
        assert (np.abs(sample["sdf_values"]) < 0.1).sum() >= 0.9 * near  # near-surface share


def test_frusta_profiles_are_fixed_length_and_labelled_by_count():
    family = make_family("frusta", {"profile_points": 16})
    for task in family.plan(10, {"train": 1.0}, seed=0):
        shape = family.generate(task)
        assert shape.profile.shape == (16, 2)
        assert task.class_name == f"frusta{shape.provenance['n_frusta']}"


def test_sha256_of_is_the_files_digest_across_read_blocks(tmp_path):
    """The provenance digest of source meshes and of the checkpoint a shipped verifier belongs to."""
    import hashlib

    from radar2shape.geometry.families.folder import sha256_of

    small = tmp_path / "abc.ckpt"
    small.write_bytes(b"abc")
    assert sha256_of(small) == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"  # FIPS 180-2
    data = np.random.default_rng(0).bytes(3 * (1 << 20) + 17)  # spans several 1 MiB reads
    large = tmp_path / "large.ckpt"
    large.write_bytes(data)
    assert sha256_of(large) == hashlib.sha256(data).hexdigest()
    large.write_bytes(data[:-1] + bytes([data[-1] ^ 1]))  # one bit of the last block
    assert sha256_of(large) != hashlib.sha256(data).hexdigest()
