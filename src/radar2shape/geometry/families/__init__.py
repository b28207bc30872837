"""Shape families: procedural ``frusta``, ``monocone`` and ``parts``, and ``folder`` for real mesh collections."""

from __future__ import annotations

from radar2shape.errors import UserInputError
from radar2shape.geometry.families.base import SPLITS, Family, Shape, ShapeTask, split_counts
from radar2shape.geometry.families.folder import FolderFamily
from radar2shape.geometry.families.frusta import FrustaFamily
from radar2shape.geometry.families.monocone import MonoconeFamily
from radar2shape.geometry.families.parts import PART_CLASSES, PartsFamily

FAMILIES: dict[str, type[Family]] = {
    "frusta": FrustaFamily, "monocone": MonoconeFamily, "parts": PartsFamily, "folder": FolderFamily,
}


def make_family(name: str, options: dict | None = None) -> Family:
    """The family ``name`` built from its options (the ``family_options`` config section)."""
    if name not in FAMILIES:
        raise UserInputError(f"family: unknown family {name!r}; choose from {sorted(FAMILIES)}")
    try:
        return FAMILIES[name](**(options or {}))
    except TypeError as err:
        raise UserInputError(f"family_options for {name!r}: {err}") from err


__all__ = ["FAMILIES", "PART_CLASSES", "SPLITS", "Family", "Shape", "ShapeTask", "make_family", "split_counts"]
