"""Checks a tool command runs before any work: input files exist, sizes fit in memory.

A size that cannot fit is refused up front, naming the estimate and the limit, instead of a
``MemoryError`` minutes later. The limit is ``--memory-limit-gb``, else the environment variable
``RADAR2SHAPE_MEMORY_GB``, else 80 % of the memory available when the command starts.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from radar2shape.errors import UserInputError

MEMORY_ENV = "RADAR2SHAPE_MEMORY_GB"
GIB = 1024**3


def _available_bytes() -> float:
    try:
        with open("/proc/meminfo") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 16.0 * GIB


def memory_limit_bytes(option_gb: float | None = None) -> tuple[float, str]:
    """The limit in bytes and where it came from (for the error line)."""
    if option_gb is not None:
        if not option_gb > 0:
            raise UserInputError(f"--memory-limit-gb: expected a positive number of GiB, got {option_gb}")
        return option_gb * GIB, "--memory-limit-gb"
    text = os.environ.get(MEMORY_ENV)
    if text:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not value > 0:
            raise UserInputError(f"{MEMORY_ENV}: expected a positive number of GiB, got {text!r}")
        return value * GIB, MEMORY_ENV
    return 0.8 * _available_bytes(), "80 % of available memory"


def check_memory(nbytes: float, what: str, option_gb: float | None = None) -> None:
    """Refuse work whose estimated peak memory ``nbytes`` exceeds the limit."""
    limit, source = memory_limit_bytes(option_gb)
    if nbytes > limit:
        raise UserInputError(f"{what} needs about {nbytes / GIB:.1f} GiB of memory, over the limit of "
                             f"{limit / GIB:.1f} GiB ({source}); reduce the size or raise --memory-limit-gb")


def add_memory_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--memory-limit-gb", type=float, metavar="GIB",
                        help=f"refuse work estimated to need more memory (default: ${MEMORY_ENV}, "
                             "else 80%% of the memory available)")


def check_input_file(path: str | Path, label: str, what: str) -> Path:
    """``path`` as a readable, non-folder file, or one line naming the option and what was expected."""
    path = Path(path)
    if not path.exists():
        raise UserInputError(f"{label}: no such file {path} (expected {what})")
    if path.is_dir():
        raise UserInputError(f"{label}: {path} is a folder (expected {what})")
    if not os.access(path, os.R_OK):
        raise UserInputError(f"{label}: {path} is not readable (expected {what})")
    return path
