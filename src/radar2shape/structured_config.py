"""YAML files read into typed dataclass schemas with omegaconf: the one config loader of the tool commands.

The Lightning CLI parses experiment configs (jsonargparse); everything else the project reads
from YAML (dataset builds, sweep grids) goes through :func:`load_structured`, so a typo'd key, a
wrong type (``num: sixty``) or a YAML syntax error is refused the same way everywhere: one
:class:`~radar2shape.errors.UserInputError` line naming the file and the key.

Schemas are plain dataclasses (``Optional[...]``, ``list``, ``dict``, nested dataclasses and
``Any`` for free-form sections); checks that types cannot express go in the schema's
``__post_init__`` and raise ``UserInputError`` (their message is prefixed with the file).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, TypeVar

import yaml

from radar2shape.errors import UserInputError

T = TypeVar("T")


def read_yaml(path: str | Path) -> Any:
    """The parsed YAML of ``path``; a missing file or a syntax error is one line naming the file."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"{path}: config file not found")
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        problem = getattr(err, "problem", None) or str(err).splitlines()[0]
        raise UserInputError(f"{path}: YAML syntax error{where}: {problem}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise UserInputError(f"{path}: cannot read config ({err})") from None


def structured(schema: type[T], values: Any, source: str) -> T:
    """``values`` (a mapping) checked against dataclass ``schema`` and returned as an instance.

    Unknown keys and values of the wrong type raise one line: ``SOURCE: key 'a.b': problem``.
    """
    from omegaconf import OmegaConf
    from omegaconf.errors import ConfigKeyError, MissingMandatoryValue, OmegaConfBaseException, ValidationError

    if values is None:
        values = {}
    if not isinstance(values, dict):
        raise UserInputError(f"{source}: expected a mapping of keys at the top level, got {type(values).__name__}")
    try:
        base = OmegaConf.structured(schema)
        _writable(base)
        merged = OmegaConf.merge(base, OmegaConf.create(values))
        return OmegaConf.to_object(merged)
    except UserInputError as err:
        raise UserInputError(f"{source}: {err}") from None
    except (ConfigKeyError, ValidationError, OmegaConfBaseException) as err:
        key = getattr(err, "full_key", None) or getattr(err, "key", None)
        message = str(err).splitlines()[0]
        if isinstance(err, ConfigKeyError):
            message = f"unknown key (expected one of {_field_names(schema, key)})"
        elif isinstance(err, MissingMandatoryValue):
            missing = re.search(r"missing mandatory value: ([\w.]+)", str(err))
            key = missing.group(1) if missing and not key else key
            raise UserInputError(f"{source}: missing '{key}' (required)") from None
        raise UserInputError(f"{source}: key '{key}': {message}") from None


def _writable(node) -> None:
    """Clear the read-only flag frozen dataclasses set, so a file can fill them (the instance stays frozen)."""
    from omegaconf import DictConfig, OmegaConf

    OmegaConf.set_readonly(node, None)
    if isinstance(node, DictConfig):
        for key in node.keys():
            child = node._get_node(key)
            if isinstance(child, DictConfig):
                _writable(child)


def load_structured(schema: type[T], path: str | Path) -> T:
    """Read YAML file ``path`` into dataclass ``schema`` (see :func:`structured`)."""
    return structured(schema, read_yaml(path), str(path))


def _field_names(schema: type, full_key: str | None) -> list[str]:
    """Field names of the (nested) dataclass that ``full_key`` points into."""
    from dataclasses import fields, is_dataclass
    from typing import get_type_hints

    cls = schema
    for part in (full_key or "").split(".")[:-1]:
        match = get_type_hints(cls).get(part)
        if isinstance(match, type) and is_dataclass(match):
            cls = match
        else:
            break
    return sorted(f.name for f in fields(cls))
