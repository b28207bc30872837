"""The dataset builder: records, manifest, resume after SIGKILL, shards, bad inputs."""

import json
import os
import re
import signal
import time

import numpy as np
import pytest
import trimesh
from conftest import REPO, TINY, run_builder, tiny_config

from data_modules.build import build_dataset, finalize
from data_modules.config import config_from_dict, load_build_config
from data_modules.manifest import read_manifest
from data_modules.records import RECORD_KEYS, read_record, record_path
from radar2shape.errors import UserInputError
from radar2shape.geometry.repair import is_solid


def all_records(root):
    return sorted((root / "records").glob("*/*.npz"))


def test_records_hold_every_key_with_the_documented_types(parts_dataset):
    manifest = read_manifest(parts_dataset)
    assert manifest["counts"]["train"] + manifest["counts"]["val"] + manifest["counts"]["test"] == 10
    assert manifest["classes"] and manifest["radar_stats"]["std"] > 0
    for path in all_records(parts_dataset):
        record = read_record(path)
        assert set(RECORD_KEYS) <= set(record)
        mesh = trimesh.Trimesh(record["vertices"], record["faces"], process=False)
        assert is_solid(mesh)
        lo, hi = mesh.bounds
        np.testing.assert_allclose(lo + hi, 0, atol=1e-6)
        assert (hi - lo).max() == pytest.approx(1.0, abs=1e-6)
        a, r, f = len(record["aspect_rad"]), len(record["roll_rad"]), len(record["freq_hz"])
        assert record["radar"].shape == (a, r, f) and record["radar"].dtype == np.complex64
        assert np.isfinite(record["radar"]).all() and np.abs(record["radar"]).max() > 0
        assert record["sdf_values"].dtype == np.float32 and record["occ_inside"].dtype == bool
        assert record["class_name"] == manifest["classes"][int(record["label"])]
        provenance = json.loads(record["provenance"])
        assert provenance["generator"] == "parts" and "seed" in provenance


def test_sigkill_then_resume_equals_an_uninterrupted_build(tmp_path, parts_dataset):
    root = tmp_path / "killed"
    config = TINY["parts"]
    process = run_builder("--config", str(config), "--out", str(root), "--num", "10")
    deadline = time.time() + 120
    while len(all_records(root)) < 3 and time.time() < deadline and process.poll() is None:
        time.sleep(0.05)
    assert process.poll() is None, "the build finished before it could be killed"
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    assert not (root / "manifest.json").exists()
    assert 3 <= len(all_records(root)) < 10
    resumed = run_builder("--config", str(config), "--out", str(root), "--num", "10", "--workers", "2")
    out, err = resumed.communicate(timeout=300)
    assert resumed.returncode == 0, err
    assert "already done" in out
    assert not list((root / "records").glob("*/.*.tmp*"))
    reference = all_records(parts_dataset)
    assert [p.relative_to(root) for p in all_records(root)] == [p.relative_to(parts_dataset) for p in reference]
    for path in reference:
        expected, actual = read_record(path), read_record(root / path.relative_to(parts_dataset))
        for key, value in expected.items():
            if isinstance(value, np.ndarray):
                assert value.dtype == actual[key].dtype and value.tobytes() == actual[key].tobytes(), key
            else:
                assert value == actual[key], key
    assert read_manifest(root)["splits"] == read_manifest(parts_dataset)["splits"]


def test_shards_build_independently_and_the_last_writes_the_manifest(tmp_path):
    config = tiny_config("frusta", 5)
    first = build_dataset(config, tmp_path, shard=(0, 2), progress=False)
    assert first.manifest is None and first.planned == 3
    second = build_dataset(config, tmp_path, shard=(1, 2), progress=False)
    assert second.manifest is not None and sum(second.manifest["counts"][s] for s in ("train", "val", "test")) == 5
    assert finalize(config, tmp_path) == second.manifest
    again = build_dataset(config, tmp_path, progress=False)
    assert again.built == 0 and again.already_done == 5


def test_finalize_refuses_an_unfinished_build(tmp_path):
    config = tiny_config("frusta", 4)
    build_dataset(config, tmp_path, shard=(0, 4), progress=False)
    with pytest.raises(UserInputError, match="3 of 4 records are not built"):
        finalize(config, tmp_path)


def test_resume_refuses_a_changed_config(tmp_path):
    build_dataset(tiny_config("frusta", 2), tmp_path, progress=False)
    with pytest.raises(UserInputError, match="different config.*num"):
        build_dataset(tiny_config("frusta", 3), tmp_path, progress=False)


def _bad_folder(root, big: bool = False):
    """A ModelNet-style folder mixing good meshes with every kind of bad input."""
    (root / "box" / "train").mkdir(parents=True)
    (root / "box" / "test").mkdir(parents=True)
    (root / "ball" / "train").mkdir(parents=True)
    trimesh.creation.box(extents=[1, 2, 3]).export(root / "box" / "train" / "good.off")
    trimesh.creation.icosphere(2).export(root / "ball" / "train" / "good.stl")
    (root / "box" / "train" / "text.obj").write_text("just some text\n")
    (root / "box" / "test" / "empty.off").write_text("OFF\n0 0 0\n")
    box = trimesh.creation.box()
    vertices = box.vertices.copy()
    vertices[0] = np.nan
    trimesh.Trimesh(vertices, box.faces, process=False).export(root / "box" / "test" / "nan.obj")
    soup = trimesh.util.concatenate([trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]]),
                                     trimesh.creation.box(bounds=[[1, 1, 0], [2, 2, 1]])])
    trimesh.Trimesh(soup.vertices, np.vstack([soup.faces, soup.faces[:3, ::-1]]), process=False).export(
        root / "box" / "test" / "soup.ply")
    if big:
        sphere = trimesh.creation.uv_sphere(count=[710, 710])  # ~2 million faces
        assert len(sphere.faces) >= 1_990_000
        sphere.export(root / "ball" / "train" / "huge.ply")


def _folder_config(tmp_path, source):
    text = (REPO / "conf/data/folder_tiny.yaml").read_text()
    path = tmp_path / "folder.yaml"
    path.write_text(text.replace("root: PATH/TO/MESHES", f"root: {source}"))
    return load_build_config(path)


def test_folder_build_repairs_or_skips_bad_inputs(tmp_path):
    source = tmp_path / "meshes"
    _bad_folder(source)
    summary = build_dataset(_folder_config(tmp_path, source), tmp_path / "out", progress=False)
    manifest = summary.manifest
    reasons = {entry["source"]: entry["reason"] for entry in manifest["skipped"]}
    assert set(reasons) == {"box/train/text.obj", "box/test/empty.off"}
    assert all("no triangles" in reason for reason in reasons.values())
    built = {s: sorted(ids) for s, ids in manifest["splits"].items()}
    assert built["test"] == ["box__nan", "box__soup"]
    assert sorted(built["train"] + built["val"]) == ["ball__good", "box__good"]
    assert manifest["classes"] == ["ball", "box"]
    for split, ids in built.items():
        for record_id in ids:
            record = read_record(record_path(tmp_path / "out", split, record_id), ["vertices", "faces", "provenance"])
            assert is_solid(trimesh.Trimesh(record["vertices"], record["faces"], process=False))
            assert len(json.loads(record["provenance"])["sha256"]) == 64


def test_a_folder_of_only_bad_inputs_fails_with_the_reasons(tmp_path):
    source = tmp_path / "meshes"
    source.mkdir()
    (source / "text.obj").write_text("just some text\n")
    with pytest.raises(UserInputError, match="no input could be built.*text.obj.*no triangles"):
        build_dataset(_folder_config(tmp_path, source), tmp_path / "out", progress=False)


@pytest.mark.slow
def test_folder_build_handles_a_two_million_face_mesh(tmp_path):
    source = tmp_path / "meshes"
    _bad_folder(source, big=True)
    manifest = build_dataset(_folder_config(tmp_path, source), tmp_path / "out", progress=False).manifest
    assert "ball__huge" in manifest["splits"]["train"] + manifest["splits"]["val"]
    split = "train" if "ball__huge" in manifest["splits"]["train"] else "val"
    record = read_record(record_path(tmp_path / "out", split, "ball__huge"), ["faces"])
    assert len(record["faces"]) <= manifest["config"]["mesh"]["face_budget"]


@pytest.mark.parametrize(
    "text, message",
    [
        ("family: parts\nnum: 3\nbogus: 1\n", "key 'bogus': unknown key"),
        ("num: 3\n", "missing 'family'"),
        ("family: parts\n", "'num' must be"),
        ("family: nope\nnum: 3\n", "unknown family 'nope'"),
        ("family: parts\nnum: 3\nsampling: {sdf_points: 3}\n", "key 'sampling.sdf_points': unknown key"),
        ("family: folder\nfamily_options: {root: /does/not/exist}\n", "not a directory"),
    ],
)
def test_config_errors_name_the_field(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(UserInputError, match=message or "family"):
        build_dataset(load_build_config(path), tmp_path / "out", progress=False)


@pytest.mark.parametrize(
    "text, message",
    [
        ("family: parts\nnum: 3\nseed: zero\n", r"key 'seed': .*'zero'.*Integer"),
        ("family: parts\nnum: sixty\n", r"key 'num': .*'sixty'.*Integer"),
        ("family: parts\nnum: 2.5\n", r"key 'num': .*'2.5'.*Integer"),
        ("family: parts\nnum: 0\n", r"num: expected a positive number of shapes, got 0"),
        ("family: parts\nnum: 3\nsplits: train\n", r"key 'splits': Cannot assign str"),
        ("family: parts\nnum: 3\nsplits: {train: 0, val: 0, test: 0}\n", r"splits: .*positive sum"),
        ("family: parts\nnum: 3\nsplits: {train: 1, val: -1}\n", r"splits: .*non-negative"),
        ("family: parts\nnum: 3\nfloor_db: quiet\n", r"key 'floor_db': .*'quiet'.*Float"),
        ("family: parts\nnum: [3\n", r"YAML syntax error \(line 3, column 1\)"),
        ("- family\n- parts\n", r"expected a mapping of config keys, got list"),
        ("family: nope\nnum: 3\n", r"unknown family 'nope'; choose from \['folder', 'frusta', 'monocone', 'parts', 'real'\]"),
        ("family: parts\nnum: 3\nfamily_options: {bogus: 1}\n", r"family_options: unknown key.*'bogus'.*'parts'.*segments"),
        ("family: parts\nnum: 3\nradar: {aspect_deg: {start: 0, stop: 180, count: 0}}\n",
         r"radar: aspect_deg.count: expected a positive integer, got 0"),
        ("family: parts\nnum: 3\nradar: conf/radar/nope.yaml\n", r"radar config .*nope.yaml not found"),
        ("family: folder\nfamily_options: {root: /does/not/exist}\n", r"folder.root: /does/not/exist is not a directory"),
        ("family: parts\nnum: 3\nsampling: {surface: -5}\n", r"sampling.surface: expected a positive count, got -5"),
        ("family: parts\nnum: 3\nsampling: {sdf: zero}\n", r"key 'sampling.sdf': .*Integer"),
        ("family: parts\nnum: 3\nmesh: {face_budget: 0}\n", r"mesh.face_budget: expected a positive count"),
        ("family: parts\nnum: 3\nsimulator: {method: fdtd}\n", r"simulator.method: expected 'po' or 'sbr'"),
        ("family: parts\nnum: 3\nsimulator: {bounces: 3}\n", r"simulator: key 'bounces': unknown key"),
        ("family: parts\nnum: 3\nsimulator: {edge_krho: -1}\n", r"simulator.edge_krho: expected a number >= 0, got -1"),
        ("family: parts\nnum: 3\nsimulator: {edge_order: 3}\n", r"simulator.edge_order: expected 1 .* or 2 .*got 3"),
    ],
)
def test_bad_configs_give_one_line_and_leave_nothing_behind(tmp_path, capsys, text, message):
    from radar2shape.cli import main

    path = tmp_path / "bad.yaml"
    path.write_text(text)
    out = tmp_path / "out"
    assert main(["build-data", "--config", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"error: {path}: "), err
    assert re.search(message, err), err
    assert not out.exists()


def test_num_on_the_command_line_is_checked_like_the_file(tmp_path, capsys):
    from radar2shape.cli import main

    out = tmp_path / "out"
    assert main(["build-data", "--config", str(TINY["frusta"]), "--out", str(out), "--num", "0"]) == 2
    assert "num: expected a positive number of shapes, got 0" in capsys.readouterr().err
    assert not out.exists()


def test_the_manifest_config_round_trips_through_the_schema(tmp_path):
    config = tiny_config("parts", 4)
    data = config.to_dict()
    assert config_from_dict(data) == config and config_from_dict(data).to_dict() == data
    assert isinstance(config.sampling.sdf_near_sigmas, tuple)
    assert data["radar"]["aspect_deg"] == {"start": 0.0, "stop": 180.0, "count": 16}  # conf/radar/tiny.yaml
    assert data["simulator"] == {} and data["num"] == 4 and data["splits"] == {"train": 0.6, "val": 0.2, "test": 0.2}


def test_command_prints_a_summary_and_names_a_missing_config(tmp_path, capsys):
    import argparse

    from data_modules.commands import build_data

    parser = argparse.ArgumentParser()
    build_data.configure_parser(parser)
    args = parser.parse_args(["--config", str(TINY["frusta"]), "--out", str(tmp_path / "d"), "--num", "2", "--quiet"])
    assert build_data.main(args) == 0
    assert "manifest written" in capsys.readouterr().out
    args = parser.parse_args(["--config", str(tmp_path / "missing.yaml"), "--out", str(tmp_path / "d")])
    with pytest.raises(UserInputError, match="missing.yaml"):
        build_data.main(args)
    with pytest.raises(SystemExit):
        parser.parse_args(["--config", "x", "--out", "y", "--shard", "1-2"])


def test_stale_temp_files_of_killed_writers_are_removed(tmp_path):
    """Whatever suffix the atomic writer gives its temp files (``.tmp.npz`` for records)."""
    from data_modules.records import remove_stale_temps
    from radar2shape.atomic import _temp_for as temp_path  # the writer's own naming

    folder = tmp_path / "records" / "train"
    folder.mkdir(parents=True)
    temps = [temp_path(folder / "000002.npz"), temp_path(folder / "manifest.json")]
    for path in temps + [folder / "000001.npz"]:
        path.write_bytes(b"x")
    assert remove_stale_temps(tmp_path) == 2
    assert sorted(p.name for p in folder.iterdir()) == ["000001.npz"]
