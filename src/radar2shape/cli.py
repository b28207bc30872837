"""The ``radar2shape`` console script.

Two kinds of subcommand share one entry point:
- ``fit | validate | test | predict``: the Lightning CLI in subclass mode, so a YAML config picks
  any model, baseline or DataModule by class path;
- tool commands (``simulate``, ``build-data``, ...): small argparse programs found by module name,
  so adding one never edits this file.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import sys
from collections.abc import Iterator
from dataclasses import dataclass

from radar2shape.errors import UserInputError

LIGHTNING_COMMANDS = {
    "fit": "Train a model (Lightning CLI; layered --config files, docs/configs.md).",
    "validate": "Run the validation loop of a model.",
    "test": "Test a model (--ckpt_path CKPT) with the metric callbacks.",
    "predict": "Run prediction (e.g. export Stage-1 latents).",
}


@dataclass(frozen=True)
class ToolCommand:
    module: str
    summary: str


TOOL_COMMANDS = {
    "simulate": ToolCommand("radar2shape.commands.simulate", "Simulate the radar response of a mesh."),
    "build-data": ToolCommand("data_modules.commands.build_data", "Build a dataset of shapes + radar."),
    "reconstruct": ToolCommand("radar2shape.commands.reconstruct", "Reconstruct a mesh from radar."),
    "evaluate": ToolCommand("radar2shape.commands.evaluate", "Metrics between two meshes (JSON)."),
    "sweep": ToolCommand("radar2shape.commands.sweep", "Run a grid of experiments (resumable)."),
    "report": ToolCommand("radar2shape.commands.report", "Collect runs into the paper's tables."),
}


_raise_errors = False  # set by errors_raised(): a caller that records tracebacks itself


@contextlib.contextmanager
def errors_raised() -> Iterator[None]:
    """Within this block :func:`main` raises errors instead of printing them (``radar2shape sweep``
    keeps each failed run's traceback in its folder)."""
    global _raise_errors
    previous, _raise_errors = _raise_errors, True
    try:
        yield
    finally:
        _raise_errors = previous


def _print_help() -> None:
    lines = ["usage: radar2shape [--debug] COMMAND [options]", "", "Lightning commands:"]
    lines += [f"  {name:<12} {text}" for name, text in LIGHTNING_COMMANDS.items()]
    lines += ["", "Tool commands:"]
    lines += [f"  {name:<12} {cmd.summary}" for name, cmd in TOOL_COMMANDS.items()]
    lines += ["", "Run 'radar2shape COMMAND --help' for the options of one command.",
              "--debug: show the Python traceback of an error instead of its one-line message."]
    print("\n".join(lines))


class _OneLineParser(argparse.ArgumentParser):
    """argparse whose usage errors join the one error path (one line, exit 2) instead of
    printing the usage block and exiting on their own."""

    def error(self, message: str):
        raise UserInputError(f"{self.prog}: {message} (see '{self.prog} --help')")


def run_tool(name: str, argv: list[str]) -> int:
    """Parse ``argv`` for tool ``name`` and run it; bad input is one line and exit code 2, other
    errors propagate to :func:`main`'s error path."""
    module = importlib.import_module(TOOL_COMMANDS[name].module)
    parser = _OneLineParser(prog=f"radar2shape {name}", description=TOOL_COMMANDS[name].summary)
    module.configure_parser(parser)
    try:
        return int(module.main(parser.parse_args(argv)) or 0)
    except UserInputError as err:
        if _raise_errors:
            raise
        print(f"error: {describe_error(err)}", file=sys.stderr)
        return 2


def dispatch(command: str, argv: list[str]) -> int:
    """Run one command; exceptions propagate (``radar2shape sweep`` records them per run)."""
    if command in LIGHTNING_COMMANDS:
        from radar2shape.lightning_cli import run_lightning

        return run_lightning(command, argv)
    return run_tool(command, argv)


def _known_classes() -> tuple[type[BaseException], ...]:
    """Exceptions that mean bad input or a bad environment (a file, a key, memory), not a bug."""
    import pickle

    known: list[type[BaseException]] = [UserInputError, OSError, MemoryError, pickle.UnpicklingError]
    for module, name in (("yaml", "YAMLError"), ("jsonargparse", "ArgumentError"),
                         ("omegaconf.errors", "OmegaConfBaseException")):
        loaded = sys.modules.get(module)  # only if the command imported it: never pay for an import here
        if loaded is not None and hasattr(loaded, name):
            known.append(getattr(loaded, name))
    return tuple(known)


def known_error(err: BaseException) -> BaseException | None:
    """``err`` or the first exception it was raised ``from`` that is of a known class, else None.

    Libraries wrap our errors (jsonargparse reports a DataModule's ``UserInputError`` inside a
    ValueError listing every Union member), so the cause chain is searched, outermost first; an
    error raised merely *while handling* another (``__context__``) is a bug, not bad input.
    """
    known = _known_classes()
    seen: set[int] = set()
    while err is not None and id(err) not in seen:
        seen.add(id(err))
        if isinstance(err, known):
            return err
        err = err.__cause__
    return None


def describe_error(err: BaseException) -> str:
    """One line for a known error, naming the file (OSError) or the location (YAML) it is about."""
    if isinstance(err, OSError) and (err.filename or err.strerror):
        text = err.strerror or type(err).__name__
        target = f"{err.filename} -> {err.filename2}" if err.filename2 else err.filename
        text = f"{target}: {text}" if target else text
    elif isinstance(err, MemoryError):
        text = f"out of memory{': ' + str(err) if str(err) else ''} (try smaller sizes or batches)"
    elif type(err).__module__.startswith("yaml"):
        mark = getattr(err, "problem_mark", None)
        where = f"{mark.name}, line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        text = f"YAML syntax error: {where}{getattr(err, 'problem', None) or err}"
    else:
        text = str(err) or type(err).__name__
        if not isinstance(err, UserInputError) and type(err).__name__ != "ArgumentError":
            text = f"{type(err).__name__}: {text}"
    return " ".join(text.split())


def as_disk_full(err: Exception) -> Exception:
    """A no-space error from a writer that does not go through :mod:`radar2shape.atomic` (a report's
    tables, Lightning's logs) as the same one line: the file and the space left. Else ``err``."""
    from radar2shape.atomic import disk_full, is_disk_full
    from radar2shape.errors import DiskFullError

    if isinstance(err, DiskFullError) or not is_disk_full(err):
        return err
    seen, cause = set(), err
    while cause is not None and id(cause) not in seen:
        seen.add(id(cause))
        if isinstance(cause, OSError) and cause.filename:
            return disk_full(cause.filename)
        cause = cause.__cause__ or cause.__context__
    return err


def main(args: list[str] | None = None) -> int:
    """Entry point; ``args`` defaults to ``sys.argv[1:]``. Returns the exit code.

    The one error path of the CLI: an error of a known class (bad input, a file that cannot be
    read or written, memory, YAML, config validation) is one line on stderr and exit code 2; any
    other error is one line and exit code 1, with the traceback only under
    ``radar2shape --debug COMMAND ...``.
    """
    args = list(sys.argv[1:] if args is None else args)
    debug = bool(args) and args[0] == "--debug"
    args = args[1:] if debug else args
    if not args or args[0] in ("-h", "--help"):
        _print_help()
        return 0
    if args[0] == "--version":
        from radar2shape import __version__

        print(__version__)
        return 0
    command, rest = args[0], args[1:]
    if command not in LIGHTNING_COMMANDS and command not in TOOL_COMMANDS:
        print(f"error: unknown command '{command}'; run 'radar2shape --help' for the list", file=sys.stderr)
        return 2
    try:
        with errors_raised() if debug else contextlib.nullcontext():
            return dispatch(command, rest)
    except Exception as err:  # noqa: BLE001 - the one place errors become messages
        if debug or _raise_errors:
            raise
        err = as_disk_full(err)
        known = known_error(err)
        if known is not None:
            # a tool's own message already starts with the option or file it is about
            where = "" if isinstance(known, UserInputError) and command in TOOL_COMMANDS else f"radar2shape {command}: "
            print(f"error: {where}{describe_error(known)}", file=sys.stderr)
            return 2
        first = (str(err).strip().splitlines() or [""])[0]
        print(f"error: radar2shape {command}: unexpected {type(err).__name__}: {first} "
              f"(run 'radar2shape --debug {command} ...' for the traceback)", file=sys.stderr)
        return 1


def entrypoint() -> None:
    """Console-script wrapper: exit with main()'s code."""
    os.environ.setdefault("WANDB_SILENT", "true")
    sys.exit(main())


if __name__ == "__main__":
    entrypoint()
