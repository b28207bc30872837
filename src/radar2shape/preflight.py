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


# Peak bytes per mesh face while one mesh is loaded and simulated or scored: trimesh's arrays and
# caches, the facet table, the Embree scene and the per-face work columns of the chunked kernels.
# Measured peak RSS of ``radar2shape simulate`` on icospheres of 82k and 328k faces: 1.2 kB per
# face (PO) and 1.4 kB (PO + edge currents) above a 0.14 GB start; the bound keeps a margin.
BYTES_PER_FACE = 2048
BYTES_PER_CELL = 48  # per (aspect, roll, frequency[, polarisation]) cell of a response (simulate's)
BYTES_PER_SAMPLE = 256  # per sampled point of a record (positions, distances, containment rays)
BYTES_PER_VOXEL = 32  # per cell of a repair remesh grid (distances, signs, marching cubes)
_CHUNK = 1 << 24


def _count_in_file(path: Path, needle: bytes) -> int:
    """Occurrences of ``needle`` in a file, read in chunks (no copy of a large file in memory)."""
    count, tail = 0, b""
    with open(path, "rb") as handle:
        while chunk := handle.read(_CHUNK):
            block = tail + chunk
            count += block.count(needle)
            tail = block[-(len(needle) - 1):] if len(needle) > 1 else b""  # a needle cut by the chunk end
    return count


def count_faces(path: str | Path) -> int | None:
    """The triangle count a mesh file declares, read from its header or counted without parsing
    (STL, PLY, OFF, OBJ; polygons count once); None for other formats or unreadable headers.

    Cheap enough to run before a mesh is loaded, so a mesh too large for memory is refused at once.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".stl":
            size = path.stat().st_size
            with open(path, "rb") as handle:
                head = handle.read(84)
            if len(head) == 84:
                declared = int.from_bytes(head[80:84], "little")
                if 84 + 50 * declared == size:
                    return declared
            return _count_in_file(path, b"endfacet")
        if suffix == ".ply":
            with open(path, "rb") as handle:
                for _ in range(200):
                    line = handle.readline()
                    if not line or line.strip() == b"end_header":
                        break
                    words = line.split()
                    if len(words) == 3 and words[0] == b"element" and words[1] == b"face":
                        return int(words[2])
            return None
        if suffix == ".off":
            with open(path, "rb") as handle:
                words: list[bytes] = []
                for _ in range(200):
                    line = handle.readline()
                    if not line:
                        break
                    line_words = line.split(b"#")[0].split()
                    if line_words and line_words[0].endswith(b"OFF"):  # OFF, COFF, NOFF ... header
                        line_words = line_words[1:]
                    words += line_words
                    if len(words) >= 2:
                        return int(words[1])
            return None
        if suffix == ".obj":
            with open(path, "rb") as handle:
                first = handle.read(2)
            return _count_in_file(path, b"\nf ") + (first == b"f ")
    except (OSError, ValueError):
        return None
    return None


def mesh_bytes(faces: int) -> float:
    """Peak memory of loading and simulating (or scoring) one mesh of ``faces`` triangles."""
    return float(faces) * BYTES_PER_FACE


def check_mesh_memory(faces: int, extra_bytes: float, what: str, option_gb: float | None = None) -> None:
    """Refuse a mesh of ``faces`` triangles (plus ``extra_bytes`` of other work) over the limit."""
    check_memory(mesh_bytes(faces) + extra_bytes, what, option_gb)
