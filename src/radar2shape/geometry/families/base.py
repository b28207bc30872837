"""What a shape family is to the dataset builder: a planner of tasks and a generator of shapes.

Planning is cheap and deterministic (it only names records, classes and seeds), so every
shard of a build, and every resumed run, agrees on the same task list; generating is the
expensive part and runs in the workers.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np
import trimesh

SPLITS = ("train", "val", "test")


@dataclass(frozen=True)
class ShapeTask:
    """One record to build: its split, id, class, seed, and (folder family) source file."""

    split: str
    record_id: str
    label: int
    class_name: str
    seed: int
    source: str = ""


@dataclass
class Shape:
    """A generated or loaded shape before normalisation, with how it came to be."""

    mesh: trimesh.Trimesh
    provenance: dict = field(default_factory=dict)
    profile: np.ndarray | None = None  # (r, z) points in the mesh's frame, roll-symmetric families


class Family(ABC):
    """A source of shapes; subclasses set ``name``, ``class_names`` and ``roll_symmetric``."""

    name: str = ""
    roll_symmetric: bool = False  # radar may be simulated at roll 0 and repeated along roll
    class_names: list[str]

    @abstractmethod
    def plan(self, num: int | None, splits: dict[str, float], seed: int) -> list[ShapeTask]:
        """Every task of the build, in a fixed order."""

    @abstractmethod
    def generate(self, task: ShapeTask) -> Shape:
        """The shape of ``task`` (raises ``MeshError`` for inputs that must be skipped)."""


def split_counts(num: int, fractions: dict[str, float]) -> dict[str, int]:
    """Split ``num`` shapes by ``fractions`` (floors; the remainder goes to the first split)."""
    total = sum(fractions.values())
    counts = {split: int(np.floor(num * share / total)) for split, share in fractions.items()}
    first = next(iter(counts))
    counts[first] += num - sum(counts.values())
    return counts


def procedural_tasks(num: int, splits: dict[str, float], seed: int, class_names: list[str]) -> list[ShapeTask]:
    """Balanced classes (index modulo class count) and one independent seed per record."""
    tasks = []
    for split_number, (split, count) in enumerate(split_counts(num, splits).items()):
        for index in range(count):
            record_seed = int(np.random.SeedSequence([seed, split_number, index]).generate_state(1)[0])
            label = index % len(class_names)
            tasks.append(ShapeTask(split, f"{index:06d}", label, class_names[label], record_seed))
    return tasks
