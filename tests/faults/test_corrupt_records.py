"""Damaged dataset records: ``build-data --verify`` lists exactly the bad ones (exit code 1),
``--repair`` rebuilds them byte-equal to the original build, and a training run that meets one
stops with one line naming the file and the verify command, or, with ``skip_bad_records``,
substitutes the next record and logs the count."""

from __future__ import annotations

import csv
import shutil
import zipfile

import numpy as np
import pytest

from fault_helpers import (REPO, files_of, one_error_line, radar2shape, reference_dataset,  # noqa: F401
                           tiny_config)
from data_modules.records import read_record, write_record
from radar2shape.cli import main


@pytest.fixture
def damaged(tmp_path, reference_dataset):
    """A copy of the reference dataset with four bad records of four kinds; returns (root, bad paths)."""
    root = tmp_path / "data"
    shutil.copytree(reference_dataset, root)
    records = root / "records"
    truncated = records / "train/000001.npz"  # an interrupted copy
    truncated.write_bytes(truncated.read_bytes()[: truncated.stat().st_size // 2])
    flipped = records / "val/000000.npz"  # one bit flipped inside the radar array: a CRC error
    data = bytearray(flipped.read_bytes())
    with zipfile.ZipFile(flipped) as archive:
        info = archive.getinfo("radar.npy")
    data[info.header_offset + info.FileHeader().__len__() + 200] ^= 0x10
    flipped.write_bytes(bytes(data))
    nan = records / "train/000002.npz"  # readable, but not finite
    arrays = read_record(nan)
    arrays["sdf_values"][7] = np.nan
    write_record(nan, {k: np.str_(v) if isinstance(v, str) else v for k, v in arrays.items()})
    missing = records / "test/000000.npz"
    missing.unlink()
    return root, {truncated: "BadZipFile", flipped: "CRC", nan: "sdf_values: 1 non-finite", missing: "missing"}


def test_verify_lists_each_bad_record_and_repair_restores_the_original_bytes(
        damaged, tiny_config, reference_dataset, capsys):
    root, bad = damaged
    assert main(["build-data", "--verify", str(reference_dataset)]) == 0
    assert capsys.readouterr().out.splitlines() == [f"verified 6 records in {reference_dataset}: all good"]

    assert main(["build-data", "--verify", str(root)]) == 1
    out = capsys.readouterr().out.splitlines()
    listed = [line for line in out if line.startswith("bad: ")]
    assert len(listed) == len(bad)
    for path, words in bad.items():
        (line,) = [line for line in listed if line.startswith(f"bad: {path}: ")]
        assert words in line, line
    assert f"verified 6 records in {root}: 4 bad" in out

    assert main(["build-data", "--verify", str(root), "--repair", "--config", str(tiny_config)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "repaired 4 file(s); verified 6 records: all good"
    assert files_of(root) == files_of(reference_dataset)


def test_repair_refuses_another_config_and_writes_nothing(damaged, tmp_path, tiny_config, capsys):
    root, bad = damaged
    other = tmp_path / "other.yaml"
    other.write_text(tiny_config.read_text().replace("seed: 0", "seed: 1"))
    before = files_of(root)
    assert main(["build-data", "--verify", str(root), "--repair", "--config", str(other)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --config: differs from the config") and "changed: seed" in err
    assert files_of(root) == before


FIT = ["fit", "--config", "{module}", "--model", str(REPO / "conf/model/tmnet_tiny.yaml")]
MODULE = """\
seed_everything: 0
trainer: {accelerator: cpu, max_epochs: 1, enable_progress_bar: false, enable_model_summary: false,
          limit_val_batches: 0, num_sanity_val_steps: 0, log_every_n_steps: 1}
data:
  class_path: data_modules.ShapeDataModule
  init_args: {root: ROOT, batch_size: 2, num_workers: 2, observability: full,
              points: {train: {surface: 256, sdf: 512}}}
"""


def _fit(tmp_path, root, *extra):
    module = tmp_path / "module.yaml"
    module.write_text(MODULE.replace("ROOT", str(root)))
    return radar2shape("fit", "--config", module, "--model", REPO / "conf/model/tmnet_tiny.yaml",
                       f"--trainer.default_root_dir={tmp_path / 'runs'}", *extra)


def test_training_on_a_truncated_record_stops_with_one_line_from_the_worker(damaged, tmp_path):
    root, _ = damaged
    result = _fit(tmp_path, root)
    assert result.returncode == 2
    line = one_error_line(result, tool=False)
    assert line == (f"error: radar2shape fit: {root}/records/train/000001.npz: damaged dataset record (BadZipFile: "
                    f"File is not a zip file); list every bad record with 'radar2shape build-data --verify {root}'")
    assert list((tmp_path / "runs").rglob("*.ckpt")) == []


@pytest.mark.slow
def test_skip_bad_records_substitutes_the_next_record_and_logs_the_count(damaged, tmp_path):
    from data_modules import ShapeDataModule

    root, _ = damaged
    dataset = ShapeDataModule(str(root), skip_bad_records=True, observability="full").dataset("train")
    substitute, following = dataset[(0, 1)], dataset[(0, 3)]  # 1 truncated, 2 not finite but readable
    assert bool(substitute.pop("record_skipped")) and not bool(following.pop("record_skipped"))
    assert int(substitute["index"]) == 2  # the next readable record, the same in every worker and epoch
    assert dataset[(0, 1)]["radar"].equal(dataset[(0, 2)]["radar"])

    result = _fit(tmp_path, root, "--data.init_args.skip_bad_records=true")
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert "warning: epoch 0: 1 train item(s) came from a substitute for a damaged record" in result.stderr
    (metrics,) = (tmp_path / "runs").rglob("metrics.csv")
    rows = [row for row in csv.DictReader(metrics.open()) if row.get("train/skipped_records")]
    assert [float(row["train/skipped_records"]) for row in rows] == [1.0]


def test_repair_refuses_while_a_build_writes_the_folder(damaged, tiny_config, capsys):
    """A repair takes the build lock: beside a running build-data it refuses and writes nothing."""
    from data_modules.build import lock_name
    from radar2shape.locking import folder_lock

    root, _ = damaged
    before = files_of(root)
    with folder_lock(root, lock_name((0, 1)), "build-data", "--out"):
        assert main(["build-data", "--verify", str(root), "--repair", "--config", str(tiny_config)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("error: --repair: ") and "in use by build-data" in err and "\n" not in err
        assert {k: v for k, v in files_of(root).items() if not k.endswith(".lock")} == before  # only the held lock is new
