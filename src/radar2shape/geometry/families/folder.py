"""The ``folder`` family: a user's folder of mesh files, e.g. ModelNet40 or Manifold40.

Layouts:
- ModelNet: ``<root>/<class>/{train,test}/*.off`` (any supported suffix). The folder's train/test
  split is kept; ``val_fraction`` of each class's train files become the val split.
- Anything else: every mesh file below ``root``; the class is the first folder under ``root``
  ("default" for files directly in it) and the split follows ``splits`` fractions.
Split membership and the ``num`` cap use a stable hash of each file's relative path, so adding
files never moves existing ones between splits.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np

from radar2shape.errors import UserInputError
from radar2shape.geometry.families.base import Family, Shape, ShapeTask
from radar2shape.geometry.mesh_io import MESH_SUFFIXES, load_mesh


def stable_unit(text: str) -> float:
    """A number in [0, 1) fixed by ``text`` (the same on every machine and Python run)."""
    return int.from_bytes(hashlib.sha1(text.encode()).digest()[:8], "big") / 2.0**64


def sha256_of(path: Path) -> str:
    """Hex digest of a file, for provenance."""
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _record_id(relative: str) -> str:
    """A file-name-safe id from a relative path (``chair/train/chair_0001.off`` -> ``chair__chair_0001``)."""
    parts = Path(relative).with_suffix("").parts
    parts = [p for p in parts if p not in ("train", "test")]
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", "__".join(parts))


class FolderFamily(Family):
    """Meshes from a folder, repaired and normalised by the builder."""

    name = "folder"

    def __init__(self, root: str, val_fraction: float = 0.1):
        self.root = Path(root).expanduser()
        if not self.root.is_dir():
            raise UserInputError(f"folder.root: {self.root} is not a directory of meshes")
        self.val_fraction = val_fraction
        self.files = sorted(
            p.relative_to(self.root).as_posix() for p in self.root.rglob("*")
            if p.is_file() and p.suffix.lower() in MESH_SUFFIXES
        )
        if not self.files:
            raise UserInputError(f"folder.root: no mesh files ({', '.join(MESH_SUFFIXES)}) below {self.root}")
        self.modelnet = all(len(Path(f).parts) == 3 and Path(f).parts[1] in ("train", "test") for f in self.files)
        self.class_names = sorted({Path(f).parts[0] if len(Path(f).parts) > 1 else "default" for f in self.files})

    def _split(self, relative: str, splits: dict[str, float]) -> str:
        unit = stable_unit(relative)
        if self.modelnet:
            folder_split = Path(relative).parts[1]
            return "val" if folder_split == "train" and unit < self.val_fraction else folder_split
        edges = np.cumsum(list(splits.values())) / sum(splits.values())
        return list(splits)[int(np.searchsorted(edges, unit, side="right"))]

    def plan(self, num, splits, seed):
        files = self.files
        if num is not None and num < len(files):
            files = sorted(sorted(files, key=lambda f: stable_unit(f"{seed}:{f}"))[:num])
        tasks = []
        for relative in files:
            parts = Path(relative).parts
            class_name = parts[0] if len(parts) > 1 else "default"
            tasks.append(ShapeTask(self._split(relative, splits), _record_id(relative),
                                   self.class_names.index(class_name), class_name,
                                   int(stable_unit(f"{seed}:{relative}") * 2**32), source=relative))
        ids = [(t.split, t.record_id) for t in tasks]
        if len(set(ids)) != len(ids):
            raise UserInputError(f"folder.root: two files below {self.root} map to the same record id")
        return tasks

    def generate(self, task: ShapeTask) -> Shape:
        path = self.root / task.source
        return Shape(load_mesh(path), {"generator": self.name, "source": task.source, "sha256": sha256_of(path)})
