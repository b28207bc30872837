"""Errors that reach the user as one clear line instead of a deep traceback."""

from __future__ import annotations

import re

# A DataLoader worker re-raises an error in the main process as ``type(message)`` with the whole
# worker traceback as the message; the last traceback line holds the original message.
_WORKER_WRAPPED = re.compile(r"^Caught \w+ in DataLoader worker process \d+\.\nOriginal Traceback", re.S)


def _unwrapped(message: str) -> str:
    """The original one-line message of an error re-raised from a DataLoader worker, else ``message``."""
    if not isinstance(message, str) or not _WORKER_WRAPPED.match(message):
        return message
    last = message.rstrip().splitlines()[-1]
    _, sep, text = last.partition(": ")
    return text if sep else last


class UserInputError(ValueError):
    """Bad input from a user: the message names the file/field and what was expected.

    Raised in a DataLoader worker it keeps its one line: torch rebuilds it in the main process
    from the worker's traceback text, which is cut back to the original message here.
    """

    def __init__(self, *args):
        if len(args) == 1:
            args = (_unwrapped(args[0]),)
        super().__init__(*args)


class MeshError(UserInputError):
    """A mesh file or mesh that cannot become a record (the message says why)."""


class DiskFullError(UserInputError, OSError):
    """A write that found no space (or quota) left: names the target and the free space.

    Also an ``OSError``, so code that tolerates a failed optional write (a cache) still does.
    """


class BadRecordError(UserInputError):
    """A dataset record that cannot be read (truncated, corrupt, wrong keys): names the file and
    the command that lists every bad record."""
