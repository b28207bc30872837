"""Lightning CLI for ``radar2shape fit|validate|test|predict`` with the project's defaults.

Defaults a user would otherwise repeat in every config: a CSV logger plus an offline wandb logger
(no account, no network) under ``trainer.default_root_dir``, seed 0, and one-line errors for a
missing config file, an unknown key or a class that is not a reconstruction model/DataModule
instead of a page of usage text.
"""

from __future__ import annotations

import os
import sys

import lightning as L
from lightning.pytorch.cli import LightningCLI
from lightning.pytorch.loggers import CSVLogger, WandbLogger

DEFAULT_ROOT_DIR = "runs/default"


def default_loggers(root_dir: str) -> list:
    """CSV first (it names the run folder: config, metrics.csv, checkpoints), then wandb offline.

    ``WANDB_MODE=disabled`` (the tests set it) leaves wandb out entirely.
    """
    csv = CSVLogger(save_dir=root_dir, name="")
    if os.environ.get("WANDB_MODE") == "disabled":
        return [csv]
    return [csv, WandbLogger(save_dir=root_dir, project="radar2shape", offline=True)]


class Radar2ShapeCLI(LightningCLI):
    """LightningCLI whose loggers default to :func:`default_loggers` under the run's root dir."""

    def _instantiate_trainer(self, config: dict, callbacks: list) -> L.Trainer:
        config = dict(config)
        if not config.get("default_root_dir"):
            config["default_root_dir"] = DEFAULT_ROOT_DIR
        if config.get("logger") in (None, True):
            config["logger"] = default_loggers(config["default_root_dir"])
        return super()._instantiate_trainer(config, callbacks)


def _one_line(message: str) -> str:
    return " ".join(str(message).split())


def run_lightning(command: str, argv: list[str]) -> int:
    """Run one Lightning subcommand; argument errors become one line on stderr and exit code 2.

    Models must be :class:`ReconstructionModel` s and DataModules :class:`ReconstructionDataModule` s,
    so a config naming any other class is refused while parsing, before anything is built.
    """
    from jsonargparse import ArgumentError

    from radar2shape.datamodule import ReconstructionDataModule
    from radar2shape.models.base import ReconstructionModel

    # Lightning relaunches DDP ranks 1.. from sys.argv, so it must hold this very command however we
    # were started (console script or python -m); the CLI parses it from there.
    saved_argv, sys.argv = sys.argv, [*(sys.argv[:1] or ["radar2shape"]), command, *argv]
    try:
        Radar2ShapeCLI(
            model_class=ReconstructionModel,
            datamodule_class=ReconstructionDataModule,
            subclass_mode_model=True,
            subclass_mode_data=True,
            seed_everything_default=0,
            save_config_kwargs={"overwrite": True},
            parser_kwargs={"exit_on_error": False},
        )
    except ArgumentError as err:
        print(f"error: radar2shape {command}: {_one_line(err)}", file=sys.stderr)
        return 2
    finally:
        sys.argv = saved_argv
    return 0
