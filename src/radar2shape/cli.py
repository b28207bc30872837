"""The ``radar2shape`` console script.

Two kinds of subcommand share one entry point:
- ``fit | validate | test | predict``: the Lightning CLI in subclass mode, so a YAML config picks
  any model, baseline or DataModule by class path;
- tool commands (``simulate``, ``build-data``, ...): small argparse programs found by module name,
  so adding one never edits this file.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from dataclasses import dataclass

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


def _print_help() -> None:
    lines = ["usage: radar2shape COMMAND [options]", "", "Lightning commands:"]
    lines += [f"  {name:<12} {text}" for name, text in LIGHTNING_COMMANDS.items()]
    lines += ["", "Tool commands:"]
    lines += [f"  {name:<12} {cmd.summary}" for name, cmd in TOOL_COMMANDS.items()]
    lines += ["", "Run 'radar2shape COMMAND --help' for the options of one command."]
    print("\n".join(lines))


def run_tool(name: str, argv: list[str]) -> int:
    """Parse ``argv`` for tool ``name`` and run it, turning bad input into a one-line error."""
    from radar2shape.errors import UserInputError

    module = importlib.import_module(TOOL_COMMANDS[name].module)
    parser = argparse.ArgumentParser(prog=f"radar2shape {name}", description=TOOL_COMMANDS[name].summary)
    module.configure_parser(parser)
    args = parser.parse_args(argv)
    try:
        return int(module.main(args) or 0)
    except UserInputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


def main(args: list[str] | None = None) -> int:
    """Entry point; ``args`` defaults to ``sys.argv[1:]``. Returns the exit code."""
    args = list(sys.argv[1:] if args is None else args)
    if not args or args[0] in ("-h", "--help"):
        _print_help()
        return 0
    if args[0] == "--version":
        from radar2shape import __version__

        print(__version__)
        return 0
    command, rest = args[0], args[1:]
    if command in LIGHTNING_COMMANDS:
        from radar2shape.lightning_cli import run_lightning

        return run_lightning(command, rest)
    if command in TOOL_COMMANDS:
        return run_tool(command, rest)
    print(f"error: unknown command '{command}'; run 'radar2shape --help' for the list", file=sys.stderr)
    return 2


def entrypoint() -> None:
    """Console-script wrapper: exit with main()'s code."""
    os.environ.setdefault("WANDB_SILENT", "true")
    sys.exit(main())


if __name__ == "__main__":
    entrypoint()
