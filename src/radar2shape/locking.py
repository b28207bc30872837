"""One writer per folder: an exclusive ``fcntl.flock`` on a lock file inside the folder.

The kernel releases a flock when its holder ends, however it ends (SIGKILL, a crash, a node
reboot), so a lock is never left held by a dead process on a local file system; the file also
names its holder (pid, host, start time) for the message of a refused second writer. The holder
removes the file when it releases the lock; an acquirer that locked a file just removed by the
previous holder notices (the path names another inode) and locks the new one.

On a network file system flock is emulated by the server's byte-range locks: a node that died
without telling the server can leave a lock held for the server's lease time. Then, and only
when the named holder is gone, deleting the lock file clears it.
"""

from __future__ import annotations

import contextlib
import datetime
import fcntl
import json
import os
import socket
import time
from collections.abc import Iterator
from pathlib import Path

from radar2shape.errors import UserInputError

_ATTEMPTS = 5  # a reader's brief shared probe (holder_of) must not refuse a writer
_RETRY_SECONDS = 0.05


def _holder_text(info: dict | None) -> str:
    if not info:
        return "a process that is just starting"
    return f"pid {info.get('pid')} on host {info.get('host')}, started {info.get('started')}"


def _read_holder(path: Path) -> dict | None:
    try:
        info = json.loads(path.read_text() or "null")
    except (OSError, ValueError):
        return None
    return info if isinstance(info, dict) else None


def _try_lock(path: Path) -> int | None:
    """An open descriptor holding an exclusive lock on ``path``, or None if another holds it."""
    for attempt in range(_ATTEMPTS):
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            time.sleep(_RETRY_SECONDS)
            continue
        try:
            current = os.stat(path).st_ino
        except FileNotFoundError:
            current = None
        if current == os.fstat(fd).st_ino:
            return fd
        os.close(fd)  # the previous holder removed this file while we waited for it: lock the new one
    return None


@contextlib.contextmanager
def folder_lock(folder: str | Path, name: str, what: str, label: str) -> Iterator[Path]:
    """Hold the exclusive lock ``folder/name`` for the block, else refuse at once.

    ``what`` names the writer (``a sweep``), ``label`` starts the error line. The refusal is a
    :class:`UserInputError` naming the holder and how to clear a stale lock. Creates ``folder``.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    fd = _try_lock(path)
    if fd is None:
        raise UserInputError(
            f"{label}: {folder} is in use by {what} ({_holder_text(_read_holder(path))}); wait for it to end "
            f"(its lock goes with it), or, only if that process is gone and the lock stays, delete {path}")
    try:
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "started": datetime.datetime.now().astimezone().isoformat(timespec="seconds")}
        os.ftruncate(fd, 0)
        os.write(fd, (json.dumps(info) + "\n").encode())
        yield path
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)  # while still holding it: see the module docstring
        os.close(fd)


def holder_of(folder: str | Path, name: str) -> dict | None:
    """The holder (pid, host, started) of ``folder/name`` if a live process holds it, else None.

    Probes with a shared lock for an instant; creates nothing.
    """
    path = Path(folder) / name
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return _read_holder(path) or {}
    finally:
        os.close(fd)
    return None
