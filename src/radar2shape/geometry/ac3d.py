"""A small reader for AC3D (``.ac``) files, the format of the FlightGear aircraft and scenery models.

No library on PyPI that the project already depends on reads AC3D (trimesh does not; the assimp
bindings need a system library), and the part of the format a radar target needs is small:

- ``OBJECT`` blocks form a tree (``kids N`` is followed by N child objects). Each object may carry
  ``loc x y z`` (a translation) and ``rot`` (nine numbers, a 3x3 matrix read row by row). A vertex
  ``v`` of an object is placed in its parent's frame as ``rot @ v + loc``, and so on up the tree.
- ``numvert N`` is followed by N vertex lines (extra numbers, e.g. normals, are ignored).
- ``numsurf N`` is followed by N surfaces: ``SURF flags``, optionally ``mat i``, then ``refs M``
  and M lines ``index u v``. The low four bits of ``flags`` give the type: 0 polygon (fan
  triangulated), 4 triangle strip; 1 closed line and 2 line hold no area and are skipped.
- ``data N`` is followed by N characters of free text (it may span lines).
- A ``kids`` count larger than the children the file holds (common in exported files) ends the
  object at the end of the file instead of failing.
Materials, textures, names, crease angles and other per-object tokens are read past and ignored.
The result is in the file's own frame and units: AC3D models are y up (``geometry.frames``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from radar2shape.errors import MeshError

SURF_POLYGON, SURF_CLOSED_LINE, SURF_LINE, SURF_TRIANGLE_STRIP = 0, 1, 2, 4


class _Lines:
    """A cursor over the file's lines that can also hand out raw characters (``data`` blocks)."""

    def __init__(self, text: str, name: str):
        self.lines = text.splitlines()
        self.index = 0
        self.name = name

    def next(self) -> list[str] | None:
        """The next non-empty line split into tokens, or None at the end."""
        while self.index < len(self.lines):
            line = self.lines[self.index].strip()
            self.index += 1
            if line:
                return line.split()
        return None

    def need(self, what: str) -> list[str]:
        tokens = self.next()
        if tokens is None:
            raise MeshError(f"{self.name}: file ends inside {what} (line {self.index})")
        return tokens

    def skip_chars(self, count: int) -> None:
        """Consume ``count`` characters of a ``data`` block, counting line breaks as one."""
        while count > 0 and self.index < len(self.lines):
            count -= len(self.lines[self.index]) + 1
            self.index += 1


def _floats(tokens: list[str], count: int, where: str, name: str) -> np.ndarray:
    try:
        values = np.array([float(t) for t in tokens[:count]], dtype=np.float64)
    except ValueError:
        values = np.array([])
    if len(values) != count:
        raise MeshError(f"{name}: expected {count} numbers in {where}, got {' '.join(tokens)!r}")
    return values


def _int(token: str, where: str, name: str) -> int:
    try:
        return int(token, 0) if token.lower().startswith("0x") else int(token)
    except ValueError:
        raise MeshError(f"{name}: expected an integer in {where}, got {token!r}") from None


def _triangles(kind: int, refs: list[int]) -> list[tuple[int, int, int]]:
    """Triangles of one surface: a fan over a polygon, alternating triangles over a strip."""
    if kind == SURF_POLYGON:
        return [(refs[0], refs[i], refs[i + 1]) for i in range(1, len(refs) - 1)]
    return [(refs[i], refs[i + 1], refs[i + 2]) if i % 2 == 0 else (refs[i + 1], refs[i], refs[i + 2])
            for i in range(len(refs) - 2)]


def _read_object(lines: _Lines, parent: np.ndarray, out_vertices: list, out_faces: list, stats: dict) -> None:
    """Read one OBJECT block (its header line already consumed) and its children, depth first."""
    name = lines.name
    rotation = np.eye(3)
    location = np.zeros(3)
    vertices = np.zeros((0, 3))
    faces: list[tuple[int, int, int]] = []
    while True:
        tokens = lines.need("an OBJECT")
        key = tokens[0]
        if key == "loc":
            location = _floats(tokens[1:], 3, "loc", name)
        elif key == "rot":
            rotation = _floats(tokens[1:], 9, "rot", name).reshape(3, 3)
        elif key == "data":
            lines.skip_chars(_int(tokens[1], "data", name) if len(tokens) > 1 else 0)
        elif key == "numvert":
            count = _int(tokens[1], "numvert", name)
            vertices = np.array([_floats(lines.need("numvert"), 3, "a vertex", name) for _ in range(count)])
            vertices = vertices.reshape(-1, 3)
        elif key == "numsurf":
            for _ in range(_int(tokens[1], "numsurf", name)):
                faces.extend(_read_surface(lines, len(vertices), stats))
        elif key == "kids":
            local = np.eye(4)
            local[:3, :3], local[:3, 3] = rotation, location
            transform = parent @ local
            if faces:
                placed = vertices @ transform[:3, :3].T + transform[:3, 3]
                offset = sum(len(v) for v in out_vertices)
                out_vertices.append(placed)
                out_faces.append(np.asarray(faces, dtype=np.int64) + offset)
            for _ in range(_int(tokens[1], "kids", name)):
                header = lines.next()
                if header is None:  # many exported files announce more children than they hold
                    stats["missing_kids"] += 1
                    return
                if header[0] != "OBJECT":
                    raise MeshError(f"{name}: expected a child OBJECT at line {lines.index}, got {header[0]!r}")
                _read_object(lines, transform, out_vertices, out_faces, stats)
            return
        # name, texture, texrep, texoff, crease, url, hidden, locked, folded, subdiv, ...: not geometry


def _read_surface(lines: _Lines, num_vertices: int, stats: dict) -> list[tuple[int, int, int]]:
    name = lines.name
    header = lines.need("a SURF")
    if header[0] != "SURF" or len(header) < 2:
        raise MeshError(f"{name}: expected SURF at line {lines.index}, got {' '.join(header)!r}")
    kind = _int(header[1], "SURF", name) & 0xF
    tokens = lines.need("a SURF")
    if tokens[0] == "mat":
        tokens = lines.need("a SURF")
    if tokens[0] != "refs" or len(tokens) < 2:
        raise MeshError(f"{name}: expected refs at line {lines.index}, got {' '.join(tokens)!r}")
    refs = [_int(lines.need("refs")[0], "refs", name) for _ in range(_int(tokens[1], "refs", name))]
    if kind not in (SURF_POLYGON, SURF_TRIANGLE_STRIP):
        stats["lines" if kind in (SURF_LINE, SURF_CLOSED_LINE) else "unknown"] += 1
        return []
    if refs and (min(refs) < 0 or max(refs) >= num_vertices):
        raise MeshError(f"{name}: surface refers to vertex {max(refs)} of {num_vertices} (line {lines.index})")
    if len(refs) < 3:
        stats["degenerate"] += 1
        return []
    return _triangles(kind, refs)


def read_ac3d(path: str | Path) -> trimesh.Trimesh:
    """All polygon surfaces of an AC3D file as one triangle mesh, placed by the object tree.

    Raises :class:`MeshError` for a file that is not AC3D, is cut short, or holds no polygon.
    ``mesh.metadata["ac3d_skipped"]`` counts the surfaces left out (lines, unknown types, fewer
    than three vertices) and the announced children the file did not hold.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="latin-1")
    except OSError as err:
        raise MeshError(f"{path}: cannot be read ({err.strerror or err})") from err
    lines = _Lines(text, str(path))
    first = lines.next()
    if not first or not first[0].startswith("AC3D"):
        raise MeshError(f"{path}: not an AC3D file (no 'AC3D' header)")
    vertices: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    stats = {"lines": 0, "unknown": 0, "degenerate": 0, "missing_kids": 0}
    while (tokens := lines.next()) is not None:
        if tokens[0] == "OBJECT":
            _read_object(lines, np.eye(4), vertices, faces, stats)
        elif tokens[0] != "MATERIAL":
            raise MeshError(f"{path}: unexpected {tokens[0]!r} at line {lines.index} (expected MATERIAL or OBJECT)")
    if not faces:
        raise MeshError(f"{path}: no polygon surfaces")
    mesh = trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=False, validate=False)
    mesh.metadata["ac3d_skipped"] = stats
    return mesh
