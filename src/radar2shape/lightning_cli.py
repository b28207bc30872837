"""Lightning CLI for ``radar2shape fit|validate|test|predict`` with the project's defaults.

Defaults a user would otherwise repeat in every config: a CSV logger plus an offline wandb logger
(no account, no network) under ``trainer.default_root_dir``, seed 0, and one-line errors for a
missing config file, an unknown key or a class that is not a reconstruction model/DataModule
instead of a page of usage text.

A run that cannot start leaves nothing behind: ``--ckpt_path`` is loaded through
:func:`radar2shape.checkpoints.load_checkpoint` right after parsing, and the model and DataModule
(which checks its data folder) are built before the Trainer, all before the run folder and its
``config.yaml`` (written atomically) exist.

A fit cut by SIGTERM (a scheduler's preemption) saves ``last.ckpt`` in the run's checkpoint folder
at the batch where Lightning's signal handler stopped it (:class:`PreemptionCheckpoint`), prints one
line with the command that resumes it, and exits with :data:`radar2shape.preemption.EXIT_CODE`.
"""

from __future__ import annotations

import logging
import os
import random
import shlex
import sys

import lightning as L
import numpy as np
import torch
from lightning.pytorch.callbacks import Callback, ModelCheckpoint
from lightning.pytorch.cli import LightningCLI, SaveConfigCallback
from lightning.pytorch.loggers import CSVLogger, WandbLogger
from lightning.pytorch.utilities.exceptions import SIGTERMException

from radar2shape import preemption

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


def signal_checkpoint_path(trainer: L.Trainer) -> str:
    """``last.ckpt`` in the folder the run's ModelCheckpoint writes to (else ``<log dir>/checkpoints``)."""
    callback = trainer.checkpoint_callback
    if isinstance(callback, ModelCheckpoint) and callback.dirpath:
        return os.path.join(callback.dirpath, callback.CHECKPOINT_NAME_LAST + callback.FILE_EXTENSION)
    return os.path.join(trainer.log_dir or trainer.default_root_dir, "checkpoints", "last.ckpt")


class PreemptionCheckpoint(Callback):
    """Saves ``last.ckpt`` when SIGTERM stops a fit, and puts the random states in every checkpoint.

    Lightning's SignalConnector turns SIGTERM into ``trainer.received_sigterm``; its loops then raise
    ``SIGTERMException`` after the running batch, which reaches :meth:`on_exception` here. The random
    states (torch, numpy, Python) make a fit resumed at an epoch boundary draw the same shuffles as
    the uninterrupted one (Lightning restores the weights, optimizer and loops, not the generators).
    """

    saved: str | None = None  # the checkpoint the last SIGTERM saved, for the resume line

    def state_dict(self) -> dict:
        kind, keys, position, has_gauss, cached = np.random.get_state()
        state = {"torch": torch.get_rng_state(), "numpy": [kind, torch.from_numpy(keys.astype(np.int64)), position,
                                                          has_gauss, cached],
                 "python": list(random.getstate())}
        if torch.cuda.is_available() and torch.cuda.is_initialized():
            state["cuda"] = torch.cuda.get_rng_state_all()
        return state

    def load_state_dict(self, state: dict) -> None:
        torch.set_rng_state(state["torch"])
        kind, keys, position, has_gauss, cached = state["numpy"]
        np.random.set_state((kind, keys.numpy().astype(np.uint32), position, has_gauss, cached))
        version, internal, gauss = state["python"]
        random.setstate((version, tuple(internal), gauss))
        if "cuda" in state and torch.cuda.is_available():
            torch.cuda.set_rng_state_all(state["cuda"])

    def on_exception(self, trainer: L.Trainer, pl_module: L.LightningModule, exception: BaseException) -> None:
        if not isinstance(exception, SIGTERMException) or trainer.state.fn != "fit":
            return
        path = signal_checkpoint_path(trainer)
        if trainer.is_global_zero:
            from radar2shape.atomic import atomic_path

            with atomic_path(path) as temp:
                trainer.save_checkpoint(temp)
        else:
            trainer.save_checkpoint(path)  # rank zero writes; the other ranks join its barrier
        PreemptionCheckpoint.saved = path


def model_setting_keys(argv: list[str]) -> list[str]:
    """The KEYs of the ``--model.init_args.KEY VALUE`` (or ``=VALUE``) settings of a command line."""
    prefix = "--model.init_args."
    return [arg[len(prefix):].partition("=")[0] for arg in argv if isinstance(arg, str) and arg.startswith(prefix)]


class Radar2ShapeCLI(LightningCLI):
    """LightningCLI whose loggers default to :func:`default_loggers` under the run's root dir, and
    which refuses a bad ``--ckpt_path`` or data folder before anything is written."""

    def parse_arguments(self, parser, args) -> None:
        """Parse, then load ``--ckpt_path`` through the one checkpoint loader (Lightning would
        unpickle it next and fail with a traceback on a text file or an arbitrary pickle)."""
        self._command_line = list(sys.argv[1:] if args is None else args) if not isinstance(args, dict) else []
        super().parse_arguments(parser, args)
        subcommand = self.config.get("subcommand")
        ckpt_path = self.config[subcommand].get("ckpt_path") if subcommand else None
        if ckpt_path and ckpt_path not in ("last", "best", "hpc", "registry"):
            from radar2shape.checkpoints import load_checkpoint

            load_checkpoint(ckpt_path, "a Lightning checkpoint", label="--ckpt_path")

    def _parse_ckpt_path(self) -> None:
        """Lightning merges the checkpoint's saved hyperparameters over the parsed config (so a test
        needs no architecture settings); the ``--model.init_args.*`` given on the command line are
        put back over them, so a setting given for a test (the heading search, samples, guidance)
        is what it runs with, not the one the checkpoint saved."""
        subcommand = self.config.get("subcommand")
        if not subcommand or not self.config[subcommand].get("ckpt_path") or self.config[subcommand].get("model") is None:
            super()._parse_ckpt_path()
            return
        parsed = self.config[subcommand]["model"]["init_args"]
        given = {key: parsed[key] for key in model_setting_keys(self._command_line) if key in parsed}
        super()._parse_ckpt_path()
        for key, value in given.items():
            self.config[f"{subcommand}.model.init_args.{key}"] = value

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
        from radar2shape.checkpoint_io import with_atomic_checkpoint_io

        config["plugins"] = with_atomic_checkpoint_io(config.get("plugins"))  # a full disk: no truncated .ckpt
        return super()._instantiate_trainer(config, [*callbacks, PreemptionCheckpoint()])


def _one_line(message: str) -> str:
    return " ".join(str(message).split())


def _without_ckpt_path(argv: list[str]) -> list[str]:
    """``argv`` less any ``--ckpt_path`` (the resume line gives the new one)."""
    out, skip = [], False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--ckpt_path":
            skip = True
        elif not arg.startswith("--ckpt_path="):
            out.append(arg)
    return out


def _report_sigterm(command: str, argv: list[str], checkpoint: str | None) -> None:
    """The one line of a command stopped by SIGTERM (rank zero only; a sweep prints its own)."""
    from lightning.pytorch.utilities.rank_zero import rank_zero_only

    if preemption.caller_will_report() or getattr(rank_zero_only, "rank", 0) != 0:
        return
    if checkpoint:
        again = shlex.join(["radar2shape", command, *_without_ckpt_path(argv), f"--ckpt_path={checkpoint}"])
        print(f"error: radar2shape {command}: stopped by SIGTERM; saved {checkpoint}; resume with: {again}",
              file=sys.stderr, flush=True)
    else:
        again = shlex.join(["radar2shape", command, *argv])
        print(f"error: radar2shape {command}: stopped by SIGTERM; rerun: {again}",
              file=sys.stderr, flush=True)


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
    # Lightning logs "Received SIGTERM" on stderr; the one line about it is ours.
    logging.getLogger("lightning.pytorch.trainer.connectors.signal_connector").setLevel(logging.WARNING)
    PreemptionCheckpoint.saved = None
    # Lightning relaunches DDP ranks 1.. from sys.argv, so it must hold this very command however we
    # were started (console script or python -m); the CLI parses it from there.
    saved_argv, sys.argv = sys.argv, [*(sys.argv[:1] or ["radar2shape"]), command, *argv]
    try:
        with preemption.sigterm_stops():
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
            except (SIGTERMException, preemption.Preempted):
                checkpoint = PreemptionCheckpoint.saved
                _report_sigterm(command, argv, checkpoint)
                raise preemption.Preempted(checkpoint) from None
    except ArgumentError as err:  # jsonargparse's message spans lines; radar2shape.cli prints one
        from radar2shape.errors import UserInputError

        raise UserInputError(_one_line(err)) from None
    finally:
        sys.argv = saved_argv
    return 0
