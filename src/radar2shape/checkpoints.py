"""The one checkpoint loader: a file that is not a radar2shape checkpoint is one clear line.

Every command that reads a ``.ckpt`` goes through ``load_checkpoint`` so a missing file, a folder,
a text file, an arbitrary pickle (refused by torch's weights-only unpickler) or a checkpoint
without the keys a radar2shape Lightning checkpoint has are reported the same way: the file,
what it is, and what was expected. Loads are weights-only (no code runs from the file).
"""

from __future__ import annotations

from pathlib import Path

from radar2shape.errors import UserInputError

__all__ = ["load_checkpoint", "describe_file", "LIGHTNING_KEYS"]

LIGHTNING_KEYS = ("state_dict", "hyper_parameters")
_EXPECTED = "expected a .ckpt saved by 'radar2shape fit'"


def describe_file(path: Path) -> str:
    """What a file that failed to load looks like, from its first bytes (for the error line)."""
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if not head:
        return "an empty file"
    if head.startswith(b"PK\x03\x04"):
        return "a zip archive that torch cannot read (truncated or not a torch file)"
    if head.startswith(b"\x80"):
        return "a pickle that is not a weights-only torch checkpoint"
    if head.startswith(b"\x93NUMPY"):
        return "a numpy .npy array"
    if b"\0" not in head:
        try:
            head.decode("utf-8")
            return "a text file"
        except UnicodeDecodeError:
            pass
    return "a binary file of unknown format"


def load_checkpoint(path: str | Path, what: str = "a radar2shape checkpoint", *, label: str = "checkpoint",
                    required: tuple[str, ...] = LIGHTNING_KEYS) -> dict:
    """The checkpoint dict at ``path`` (CPU tensors, weights-only), or a ``UserInputError`` line.

    ``label`` names the option (e.g. ``--ckpt``); ``required`` are the keys it must hold.
    """
    path = Path(path)
    prefix = f"{label}: {path}"
    if not path.exists():
        raise UserInputError(f"{prefix} not found; {_EXPECTED}")
    if path.is_dir():
        raise UserInputError(f"{prefix} is a folder, not {what}; {_EXPECTED}")
    if path.stat().st_size == 0:
        raise UserInputError(f"{prefix} is an empty file, not {what}; {_EXPECTED}")
    import pickle
    import warnings

    import torch

    try:
        with warnings.catch_warnings():  # torch warns about pickle protocols before refusing them
            warnings.filterwarnings("ignore", message=".*pickle protocol.*")
            checkpoint = torch.load(path, map_location="cpu", weights_only=True)
    except (pickle.UnpicklingError, RuntimeError, EOFError, ValueError, TypeError, AttributeError,
            ImportError, IndexError, KeyError, UnicodeDecodeError) as err:
        raise UserInputError(f"{prefix} is {describe_file(path)}, not {what}; {_EXPECTED}") from err
    except OSError as err:
        raise UserInputError(f"{prefix} cannot be read ({err.strerror or err}); {_EXPECTED}") from err
    if not isinstance(checkpoint, dict):
        raise UserInputError(f"{prefix} holds a {type(checkpoint).__name__}, not {what}; {_EXPECTED}")
    missing = [key for key in required if key not in checkpoint]
    if missing:
        found = ", ".join(map(str, list(checkpoint)[:6])) or "none"
        raise UserInputError(f"{prefix} has no {', '.join(repr(k) for k in missing)} (keys: {found}), "
                             f"so it is not {what}; {_EXPECTED}")
    return checkpoint
