"""The one atomic-write mechanism: every output appears complete under its final name, or not at all.

A writer gets a temporary path beside the target (same folder, so ``os.replace`` is a rename on
one file system, and the real suffix kept last, so format-by-extension writers such as
``savefig`` or a mesh exporter still work); on success the file is fsynced and renamed, on any
failure the temporary file and any parent folders created for it are removed.
``atomic_paths`` does the same for several outputs of one command: nothing is renamed until
every file is written, so a command that fails half-way leaves no new file.

A write that runs out of space (ENOSPC, or EDQUOT for a quota) is turned into one
:class:`~radar2shape.errors.DiskFullError` line naming the target and the space left on its file
system, after the temporary file is removed: a full disk leaves no partial file, and the same
command completes once space is freed.

``check_output_path`` validates an output before any work is done (one clear line naming the
option and the path), so commands can check all outputs first, then write all.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import uuid
from pathlib import Path
from typing import IO, Iterator

from radar2shape.errors import DiskFullError, UserInputError

__all__ = ["atomic_path", "atomic_paths", "atomic_open", "write_text_atomic", "write_bytes_atomic",
           "check_output_path", "check_output_dir", "disk_full", "is_disk_full", "format_bytes"]

_NO_SPACE = (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))


def format_bytes(nbytes: float) -> str:
    """``nbytes`` for people: B, kB, MB, GB (powers of 1000, as ``df -H``)."""
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if abs(nbytes) >= size:
            return f"{nbytes / size:.1f} {unit}"
    return f"{int(nbytes)} B"


def is_disk_full(err: BaseException) -> bool:
    """True when ``err`` or an error it was raised from or while handling is ENOSPC / EDQUOT.

    Writers wrap the OS error (torch's zip writer raises a RuntimeError whose message carries it),
    so the chain is searched and, for a wrapped one, the message.
    """
    seen: set[int] = set()
    while err is not None and id(err) not in seen:
        seen.add(id(err))
        if isinstance(err, DiskFullError):
            return True
        if isinstance(err, OSError) and err.errno in _NO_SPACE:
            return True
        if "No space left on device" in str(err) or "Disk quota exceeded" in str(err):
            return True
        err = err.__cause__ or err.__context__
    return False


def disk_full(target: str | Path, needed: int | None = None, quota: bool = False) -> DiskFullError:
    """The one-line error for a write of ``target`` that found no space: the free space of its
    file system (``shutil.disk_usage``) and, when known, the bytes the write needed."""
    target = Path(target)
    try:
        free = format_bytes(shutil.disk_usage(_existing_ancestor(target.parent)).free) + " free"
    except OSError:
        free = "free space unknown"
    need = f"needs {format_bytes(needed)}, " if needed else ""
    what = "disk quota exceeded" if quota else "no space left on device"
    return DiskFullError(f"{target}: {what} ({need}{free} on its file system); nothing was written: "
                         "free some space and run the same command again")


def _quota(err: BaseException) -> bool:
    """True when the chain's no-space error is a quota (EDQUOT) rather than a full file system."""
    seen: set[int] = set()
    while err is not None and id(err) not in seen:
        seen.add(id(err))
        if isinstance(err, OSError) and err.errno is not None and err.errno == getattr(errno, "EDQUOT", None):
            return True
        err = err.__cause__ or err.__context__
    return False


def _temp_for(path: Path) -> Path:
    return path.with_name(f".{path.stem}.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp{path.suffix}")


def _make_parents(folder: Path) -> list[Path]:
    """Create ``folder`` and missing parents; returns the folders created (deepest last)."""
    missing = []
    probe = folder
    while not probe.exists() and probe != probe.parent:
        missing.append(probe)
        probe = probe.parent
    folder.mkdir(parents=True, exist_ok=True)
    return list(reversed(missing))


def _remove_folders(created: list[Path]) -> None:
    for folder in reversed(created):  # deepest first; only empty ones (never what others wrote)
        with contextlib.suppress(OSError):
            folder.rmdir()


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_paths(*paths: str | Path, mkdir: bool = True) -> Iterator[list[Path]]:
    """Temporary paths for ``paths``; all are renamed into place only if the block succeeds.

    The block must create every temporary file; on any exception (or a file not written) none of
    the targets changes and every temporary file and created folder is removed.
    """
    targets = [Path(p) for p in paths]
    created: list[Path] = []
    temps: list[Path] = []
    try:
        for target in targets:
            if mkdir:
                created += _make_parents(target.parent)
            temps.append(_temp_for(target))
        yield list(temps)
        for temp, target in zip(temps, targets):
            if not temp.is_file():
                raise FileNotFoundError(f"{target}: the writer produced no file")
            _fsync(temp)
        for temp, target in zip(temps, targets):
            os.replace(temp, target)
    except BaseException as err:
        for temp in temps:
            temp.unlink(missing_ok=True)
        _remove_folders(created)
        if isinstance(err, DiskFullError):  # a nested atomic writer named our temp file: name the target
            for temp, target in zip(temps, targets):
                if str(temp) in str(err):
                    raise DiskFullError(str(err).replace(str(temp), str(target))) from err.__cause__
        elif is_disk_full(err):
            target = next((t for t, tmp in zip(targets, temps) if tmp.name in str(err)), targets[0])
            raise disk_full(target, quota=_quota(err)) from err
        raise


@contextlib.contextmanager
def atomic_path(path: str | Path, mkdir: bool = True) -> Iterator[Path]:
    """A temporary path beside ``path``, renamed onto it if the block succeeds, removed otherwise."""
    with atomic_paths(path, mkdir=mkdir) as (temp,):
        yield temp


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "wb", mkdir: bool = True, **kwargs) -> Iterator[IO]:
    """``open(temp, mode)`` for writing; the file replaces ``path`` only if the block succeeds."""
    with atomic_path(path, mkdir=mkdir) as temp, open(temp, mode, **kwargs) as handle:
        yield handle


def write_bytes_atomic(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; returns the path."""
    try:
        with atomic_open(path, "wb") as handle:
            handle.write(data)
    except DiskFullError as err:  # the size is known here: say it
        raise disk_full(path, needed=len(data), quota="quota" in str(err)) from err.__cause__
    return Path(path)


def write_text_atomic(path: str | Path, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; returns the path."""
    return write_bytes_atomic(path, text.encode(encoding))


def _existing_ancestor(folder: Path) -> Path:
    probe = folder
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    return probe


def _check_folder_writable(folder: Path, label: str, path: Path) -> None:
    ancestor = _existing_ancestor(folder)
    if not ancestor.is_dir():
        raise UserInputError(f"{label}: cannot write {path}: {ancestor} is a file, not a folder")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise UserInputError(f"{label}: cannot write {path}: folder {ancestor} is read-only")


def check_output_path(path: str | Path, label: str = "output", suffixes: tuple[str, ...] | None = None,
                      overwrite: bool = True) -> Path:
    """Refuse an output file path that cannot be written, before any work is done.

    Checks: not an existing folder; its folder exists or can be created (no file in the way) and
    is writable; the suffix is one of ``suffixes`` (if given); an existing file only if
    ``overwrite``. Creates nothing.
    """
    path = Path(path)
    if str(path) in ("", "."):
        raise UserInputError(f"{label}: empty output path")
    if path.is_dir():
        raise UserInputError(f"{label}: {path} is an existing folder; expected a file path")
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise UserInputError(f"{label}: {path} has suffix {path.suffix or '(none)'!r}; "
                             f"expected one of {', '.join(suffixes)}")
    if path.exists() and not overwrite:
        raise UserInputError(f"{label}: {path} already exists")
    _check_folder_writable(path.parent, label, path)
    if path.exists() and not os.access(path, os.W_OK):
        raise UserInputError(f"{label}: {path} is read-only")
    return path


def check_output_dir(path: str | Path, label: str = "output folder") -> Path:
    """Refuse an output folder that is a file or sits in a read-only folder; creates nothing."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UserInputError(f"{label}: {path} is an existing file; expected a folder")
    _check_folder_writable(path, label, path)
    return path
