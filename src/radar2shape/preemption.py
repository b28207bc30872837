"""SIGTERM as a clean, resumable stop (a scheduler's preemption or time limit).

A scheduler sends SIGTERM, waits a grace period, then SIGKILLs. Within the grace period every
command stops where it can resume: the dataset builder keeps its finished records, a fit saves
``last.ckpt`` (see :mod:`radar2shape.lightning_cli`), a sweep leaves the cut run resumable. The
process then exits with :data:`EXIT_CODE` (128 + SIGTERM, what a shell reports for a process
killed by SIGTERM), so no scheduler takes a cut run for a finished one.

:func:`sigterm_stops` installs a handler that raises :class:`Preempted` at the next Python
bytecode: atomic writers (:mod:`radar2shape.atomic`) then remove their temporary files on the way
out. While a Lightning trainer runs, Lightning's own handler replaces this one and calls it after
its own; then this handler only records the signal and the trainer stops after the running batch.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

EXIT_CODE = 128 + signal.SIGTERM  # 143

_received = False
_caller_reports = 0  # > 0: an enclosing command (a sweep) prints the one line, not the nested fit


class Preempted(SystemExit):
    """The command was stopped by SIGTERM; a ``SystemExit`` so no ``except Exception`` records it
    as a failure, with exit code :data:`EXIT_CODE`.

    ``checkpoint``: the resumable checkpoint a fit saved; ``detail``: what was done (for the line).
    """

    def __init__(self, checkpoint: str | None = None, detail: str | None = None):
        super().__init__(EXIT_CODE)
        self.checkpoint = checkpoint
        self.detail = detail

    def __reduce__(self):  # crosses process boundaries (pool workers) with its fields
        return (Preempted, (self.checkpoint, self.detail))


def received() -> bool:
    """Whether SIGTERM arrived since the outermost :func:`sigterm_stops` began."""
    return _received


def raise_if_received() -> None:
    """Stop at a safe point if SIGTERM arrived while someone else's handler deferred it."""
    if _received:
        raise Preempted()


def _handler(signum, frame) -> None:
    global _received
    first = not _received
    _received = True
    if signal.getsignal(signal.SIGTERM) is not _handler:
        return  # called by Lightning's handler: the trainer stops after its running batch
    if first:  # a second SIGTERM must not interrupt the clean-up of the first
        raise Preempted()


def install() -> None:
    """Make SIGTERM raise :class:`Preempted` in this process for good (pool workers)."""
    signal.signal(signal.SIGTERM, _handler)


@contextlib.contextmanager
def sigterm_stops() -> Iterator[None]:
    """Within this block SIGTERM raises :class:`Preempted`; nested blocks share the outer one."""
    global _received
    if threading.current_thread() is not threading.main_thread() or signal.getsignal(signal.SIGTERM) is _handler:
        yield
        return
    _received = False
    previous = signal.signal(signal.SIGTERM, _handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def caller_reports() -> Iterator[None]:
    """Commands run within this block leave the one-line message to the caller (a sweep)."""
    global _caller_reports
    _caller_reports += 1
    try:
        yield
    finally:
        _caller_reports -= 1


def caller_will_report() -> bool:
    return _caller_reports > 0
