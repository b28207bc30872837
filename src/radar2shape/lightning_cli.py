"""Lightning CLI for ``radar2shape fit|validate|test|predict`` with the project's defaults.

Defaults a user would otherwise repeat in every config: a CSV logger plus an offline wandb logger
(no account, no network) under ``trainer.default_root_dir``, seed 0, and one-line errors for a
missing config file, an unknown key or a class that is not a reconstruction model/DataModule
instead of a page of usage text.

A run that cannot start leaves nothing behind: ``--ckpt_path`` is loaded through
:func:`radar2shape.checkpoints.load_checkpoint` right after parsing, and the model and DataModule
(which checks its data folder) are built before the Trainer, all before the run folder and its
``config.yaml`` (written atomically) exist.
"""

from __future__ import annotations

import logging
import os
import sys

import lightning as L
from lightning.pytorch.cli import LightningCLI, SaveConfigCallback
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


class AtomicSaveConfigCallback(SaveConfigCallback):
    """Writes the run's ``config.yaml`` through :mod:`radar2shape.atomic`: complete or absent."""

    def setup(self, trainer: L.Trainer, pl_module: L.LightningModule, stage: str) -> None:
        if self.already_saved or not self.save_to_log_dir:
            return super().setup(trainer, pl_module, stage)
        # ``trainer.log_dir`` is a collective call under DDP: every rank asks, or rank 0 waits forever.
        log_dir = trainer.log_dir
        if not trainer.is_global_zero:
            return super().setup(trainer, pl_module, stage)
        from radar2shape.atomic import atomic_path

        final = self.config_filename
        with atomic_path(os.path.join(log_dir, final)) as temp:
            self.config_filename = temp.name  # the parent writes here; the rename happens on success
            try:
                super().setup(trainer, pl_module, stage)
            finally:
                self.config_filename = final


class Radar2ShapeCLI(LightningCLI):
    """LightningCLI whose loggers default to :func:`default_loggers` under the run's root dir, and
    which refuses a bad ``--ckpt_path`` or data folder before anything is written."""

    def parse_arguments(self, parser, args) -> None:
        """Parse, then load ``--ckpt_path`` through the one checkpoint loader (Lightning would
        unpickle it next and fail with a traceback on a text file or an arbitrary pickle)."""
        super().parse_arguments(parser, args)
        subcommand = self.config.get("subcommand")
        ckpt_path = self.config[subcommand].get("ckpt_path") if subcommand else None
        if ckpt_path and ckpt_path not in ("last", "best", "hpc", "registry"):
            from radar2shape.checkpoints import load_checkpoint

            load_checkpoint(ckpt_path, "a Lightning checkpoint", label="--ckpt_path")

    def _set_seed(self) -> None:
        """Seed quietly: "Seed set to N" is logged once the classes are built (see
        :meth:`after_instantiate_classes`), so a refused run prints only its error line."""
        seed_log = logging.getLogger("lightning.fabric.utilities.seed")
        level = seed_log.level
        seed_log.setLevel(logging.WARNING)
        try:
            super()._set_seed()
        finally:
            seed_log.setLevel(level)

    def after_instantiate_classes(self) -> None:
        seed = self._get(self.config, "seed_everything")
        if seed is not False and seed is not None:
            from lightning.pytorch.utilities import rank_zero_info

            rank_zero_info(f"Seed set to {seed}")

    def instantiate_classes(self) -> None:
        """Build model and DataModule; an error of ours that jsonargparse wrapped (e.g. a missing
        data folder inside a Union-validation report) is raised as itself, one line."""
        from radar2shape.errors import UserInputError

        try:
            super().instantiate_classes()
        except ValueError as err:
            cause = err
            while cause is not None and not isinstance(cause, UserInputError):
                cause = cause.__cause__
            if cause is None:
                raise
            raise cause from None

    def _instantiate_trainer(self, config: dict, callbacks: list) -> L.Trainer:
        config = dict(config)
        if not config.get("default_root_dir"):
            config["default_root_dir"] = DEFAULT_ROOT_DIR
        if config.get("logger") in (None, True):
            config["logger"] = default_loggers(config["default_root_dir"])
        return super()._instantiate_trainer(config, callbacks)


def _one_line(message: str) -> str:
    return " ".join(str(message).split())


def check_config_files(argv: list[str]) -> None:
    """Read every ``--config`` file first, so a missing file or a YAML syntax error names the file
    and line (jsonargparse reports the latter as a parse error of an anonymous string)."""
    from radar2shape.structured_config import read_yaml

    for i, arg in enumerate(argv):
        if arg == "--config" and i + 1 < len(argv):
            read_yaml(argv[i + 1])
        elif arg.startswith("--config="):
            read_yaml(arg.split("=", 1)[1])


def run_lightning(command: str, argv: list[str]) -> int:
    """Run one Lightning subcommand; argument errors are raised as one-line ``UserInputError`` s.

    Models must be :class:`ReconstructionModel` s and DataModules :class:`ReconstructionDataModule` s,
    so a config naming any other class is refused while parsing, before anything is built.
    """
    from jsonargparse import ArgumentError

    from radar2shape.datamodule import ReconstructionDataModule
    from radar2shape.models.base import ReconstructionModel

    check_config_files(argv)
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
            save_config_callback=AtomicSaveConfigCallback,
            save_config_kwargs={"overwrite": True},
            parser_kwargs={"exit_on_error": False},
        )
    except ArgumentError as err:  # jsonargparse's message spans lines; radar2shape.cli prints one
        from radar2shape.errors import UserInputError

        raise UserInputError(_one_line(err)) from None
    finally:
        sys.argv = saved_argv
    return 0
