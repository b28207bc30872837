"""The console script: help lists every command, Lightning fit/test run end to end, errors are one line."""

from pathlib import Path

import pytest
import torch
import yaml

from radar2shape import cli
from radar2shape.toy import sphere_po_rcs

REPO = Path(__file__).resolve().parents[1]
TOY = str(REPO / "conf" / "experiment" / "toy_sphere.yaml")
ALL_COMMANDS = ["fit", "validate", "test", "predict", "simulate", "build-data", "reconstruct", "evaluate", "report"]


def test_help_lists_all_nine_subcommands(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in ALL_COMMANDS:
        assert f"  {name} " in out


def test_fit_help_shows_lightning_options(capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["fit", "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "--trainer.max_epochs" in out and "--model" in out and "--data" in out


def test_fit_then_test_writes_config_and_checkpoint(tmp_path, capsys):
    root = tmp_path / "run"
    code = cli.main(["fit", "--config", TOY, "--trainer.max_epochs=3", f"--trainer.default_root_dir={root}",
                     "--trainer.enable_progress_bar=false"])
    assert code == 0
    run_dir = root / "version_0"
    saved = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert saved["model"]["class_path"] == "radar2shape.toy.ToySphereRegressor"
    assert saved["seed_everything"] == 0
    checkpoints = sorted((run_dir / "checkpoints").glob("*.ckpt"))
    assert len(checkpoints) == 1
    # checkpoints keep primitive hyperparameters only, so they load without unpickling code
    state = torch.load(checkpoints[0], weights_only=True)
    assert state["hyper_parameters"]["num_freq"] == 16

    code = cli.main(["test", "--config", TOY, f"--trainer.default_root_dir={root}", f"--ckpt_path={checkpoints[0]}",
                     "--trainer.enable_progress_bar=false"])
    assert code == 0
    metrics = (root / "version_1" / "metrics.csv").read_text()
    assert "test/radius_l1" in metrics

    # a test takes the checkpoint's saved settings over the config files' (so it needs no architecture
    # settings), but a setting given on the command line stands over the checkpoint's
    state["hyper_parameters"]["lr"] = 0.123
    edited = tmp_path / "edited.ckpt"
    torch.save(state, edited)
    for version, given, expected in [(2, [], 0.123), (3, ["--model.init_args.lr=0.5"], 0.5), (4, ["--model.init_args.lr", "0.25"], 0.25)]:
        code = cli.main(["test", "--config", TOY, f"--trainer.default_root_dir={root}", f"--ckpt_path={edited}",
                         "--trainer.enable_progress_bar=false", *given])
        assert code == 0
        saved = yaml.safe_load((root / f"version_{version}" / "config.yaml").read_text())
        assert saved["model"]["init_args"]["lr"] == expected, given


def test_fast_dev_run_smoke(tmp_path):
    code = cli.main(["fit", "--config", TOY, "--trainer.fast_dev_run=true", f"--trainer.default_root_dir={tmp_path}"])
    assert code == 0


def test_missing_config_file_is_one_line_error(capsys):
    assert cli.main(["fit", "--config", "/no/such/file.yaml"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "/no/such/file.yaml" in err


def test_unknown_config_key_is_one_line_error(capsys, tmp_path):
    code = cli.main(["fit", "--config", TOY, "--model.init_args.bogus_key=3", f"--trainer.default_root_dir={tmp_path}"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bogus_key" in err


def test_unknown_command(capsys):
    assert cli.main(["frobnicate"]) == 2
    assert "unknown command 'frobnicate'" in capsys.readouterr().err


def test_toy_sphere_rcs_matches_optical_limit():
    """Large ka: the PO sphere RCS tends to pi a^2 (checks the toy data's physics)."""
    import numpy as np

    rcs = sphere_po_rcs(np.array([1.0]), np.array([30e9]))
    assert abs(rcs[0, 0] / np.pi - 1) < 1e-2


def test_toy_model_learns_radius(tmp_path):
    """The toy regressor must beat the mean-radius guess (L1 0.0875 for U[0.1, 0.45]) by 3x."""
    root = tmp_path / "run"
    assert cli.main(["fit", "--config", TOY, "--trainer.max_epochs=25", f"--trainer.default_root_dir={root}",
                     "--trainer.enable_progress_bar=false"]) == 0
    import csv

    rows = [r for r in csv.DictReader(open(root / "version_0" / "metrics.csv")) if r.get("val/radius_l1")]
    assert float(rows[-1]["val/radius_l1"]) < 0.0875 / 3


@pytest.mark.parametrize("section, class_path", [
    ("model", "torch.nn.Linear"),
    ("model", "lightning.pytorch.demos.boring_classes.BoringModel"),
    ("data", "lightning.pytorch.demos.boring_classes.BoringDataModule"),
])
def test_class_outside_the_reconstruction_bounds_is_one_line_error(capsys, tmp_path, section, class_path):
    """Only ReconstructionModel / ReconstructionDataModule subclasses parse: refused before anything runs."""
    code = cli.main(["fit", "--config", TOY, f"--{section}={class_path}", f"--trainer.default_root_dir={tmp_path}"])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: radar2shape fit: ") and class_path in err
    assert not (tmp_path / "version_0").exists()
