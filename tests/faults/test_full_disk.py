"""A full disk during a write: one ``error:`` line naming the file and the free space, exit code 2,
no partial or temporary file, and the same command completes once space is freed, with output equal
to a run on a normal disk. The disk is a real 2 MB tmpfs filled to a few records' worth."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import torch
import trimesh

from fault_helpers import (REPO, files_of, fill, leftovers, one_error_line, radar2shape, reference_dataset,  # noqa: F401
                           small_disk, tiny_config)


def test_build_data_on_a_full_disk_stops_in_one_line_and_resumes_to_the_same_dataset(
        small_disk, tiny_config, reference_dataset):
    out = small_disk / "data"
    filler = fill(small_disk, 150_000)  # build_config.json and two ~60 kB records fit, the third does not
    failed = radar2shape("build-data", "--config", tiny_config, "--out", out, "--quiet")
    assert failed.returncode == 2
    line = one_error_line(failed)
    assert "no space left on device" in line and f"{out}/records/" in line and ".npz" in line, line
    assert " free on its file system" in line and "run the same command again" in line
    assert leftovers(small_disk) == []
    written = sorted(out.rglob("*.npz"))
    assert 1 <= len(written) < 6 and not (out / "manifest.json").exists()
    for path in written:  # what is there is complete: every member reads
        with np.load(path) as data:
            assert all(data[key] is not None for key in data.files)
    filler.unlink()
    resumed = radar2shape("build-data", "--config", tiny_config, "--out", out, "--quiet")
    assert resumed.returncode == 0, resumed.stderr
    assert f"{len(written)} already done of 6" in resumed.stdout
    assert files_of(out) == files_of(reference_dataset)  # byte for byte, manifest included


def test_simulate_on_a_full_disk_writes_nothing_then_equals_a_normal_run(small_disk, tmp_path):
    mesh = tmp_path / "box.obj"
    trimesh.creation.box((1.0, 0.5, 0.25)).export(mesh)
    grid = ["--aspect-deg", "0:180:16", "--roll-deg", "0:337.5:16", "--freq-ghz", "8:12:64"]  # 131 kB response
    reference = radar2shape("simulate", mesh, "--out", tmp_path / "ref.npz", *grid)
    assert reference.returncode == 0, reference.stderr
    out = small_disk / "sim" / "r.npz"
    filler = fill(small_disk, 64_000)
    failed = radar2shape("simulate", mesh, "--out", out, *grid)
    assert failed.returncode == 2
    line = one_error_line(failed)
    assert line.startswith(f"error: {out}: no space left on device (") and "kB free" in line, line
    assert sorted(p.name for p in small_disk.rglob("*")) == ["filler.bin"]  # no file, no folder left
    filler.unlink()
    again = radar2shape("simulate", mesh, "--out", out, *grid)
    assert again.returncode == 0, again.stderr
    with np.load(out) as got, np.load(tmp_path / "ref.npz") as want:
        assert got.files == want.files
        for key in want.files:
            assert np.array_equal(got[key], want[key]), key


@pytest.mark.slow
def test_checkpoint_on_a_full_disk_is_one_line_and_no_partial_checkpoint(small_disk, tmp_path):
    """Lightning's own writer copies a temp file from /tmp onto the target, leaving a truncated
    checkpoint; the CheckpointIO the CLI adds to every trainer writes beside it and renames, or
    reports the disk."""
    fit = ["fit", "--config", REPO / "conf/trainer/cpu.yaml", "--config", REPO / "conf/experiment/toy_sphere.yaml",
           "--trainer.max_epochs=1"]
    reference = radar2shape(*fit, f"--trainer.default_root_dir={tmp_path / 'ref'}")
    assert reference.returncode == 0, reference.stderr
    (want,) = (tmp_path / "ref").rglob("*.ckpt")  # ~74 kB; config, hparams and metrics take ~16 kB
    runs = small_disk / "runs"
    filler = fill(small_disk, 40_000)
    failed = radar2shape(*fit, f"--trainer.default_root_dir={runs}")
    assert failed.returncode == 2
    line = one_error_line(failed, tool=False)
    assert line.startswith("error: radar2shape fit: ") and ".ckpt: no space left on device" in line, line
    assert list(small_disk.rglob("*.ckpt")) == [] and leftovers(small_disk) == []
    filler.unlink()
    shutil.rmtree(runs)
    again = radar2shape(*fit, f"--trainer.default_root_dir={runs}")
    assert again.returncode == 0, again.stderr
    (got,) = runs.rglob("*.ckpt")
    got_state = torch.load(got, weights_only=True)["state_dict"]
    want_state = torch.load(want, weights_only=True)["state_dict"]
    assert got_state.keys() == want_state.keys()
    assert all(torch.equal(got_state[k], want_state[k]) for k in want_state)


def test_report_on_a_full_disk_is_one_line_and_leaves_no_file(small_disk, tmp_path):
    """A report writes its tables without the atomic writer (into a staging folder moved into place at
    the end); a full disk is still one line naming the file and the space left, nothing stays, and the
    rerun after space is freed writes the same report as on a normal disk."""
    import sys

    sys.path.insert(0, str(REPO / "tests"))
    from test_report import finished_run

    import yaml

    runs = tmp_path / "runs"
    for name, iou in (("radar2shape-full", 0.5), ("nearest-full", 0.6)):
        finished_run(runs / name, 3.0, iou, 0.3, saved=())
    grid = tmp_path / "g.yaml"
    grid.write_text(yaml.safe_dump({"out_dir": str(runs), "runs": [{"name": "radar2shape-full"}, {"name": "nearest-full"}]}))
    reference = radar2shape("report", "--grid", grid, "--out", tmp_path / "ref")
    assert reference.returncode == 0, reference.stderr
    out = small_disk / "report"
    filler = fill(small_disk, 2_000)
    failed = radar2shape("report", "--grid", grid, "--out", out)
    assert failed.returncode == 2
    line = one_error_line(failed, tool=False)
    assert line.startswith(f"error: {out}: no space left on device (") and "free on its file system" in line, line
    assert not out.exists() and leftovers(small_disk) == []
    filler.unlink()
    again = radar2shape("report", "--grid", grid, "--out", out)
    assert again.returncode == 0, again.stderr
    assert files_of(out) == files_of(tmp_path / "ref")


def test_a_foreign_writers_no_space_error_becomes_the_one_line(tmp_path):
    """Writers outside radar2shape.atomic (Lightning's logs) raise a bare OSError: the CLI names its file."""
    import errno

    from radar2shape.cli import as_disk_full
    from radar2shape.errors import DiskFullError

    target = tmp_path / "runs" / "metrics.csv"
    try:
        try:
            raise OSError(errno.ENOSPC, "No space left on device", str(target))
        except OSError as inner:
            raise RuntimeError("logger failed") from inner
    except RuntimeError as err:
        converted = as_disk_full(err)
    assert isinstance(converted, DiskFullError)
    assert str(converted).startswith(f"{target}: no space left on device (") and "free on its file system" in str(converted)
    other = ValueError("not a disk problem")
    assert as_disk_full(other) is other
