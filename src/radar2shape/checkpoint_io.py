"""Lightning checkpoints written through :mod:`radar2shape.atomic`.

Lightning's own writer serialises to memory, writes a temporary file in the system temp folder
and moves it onto the target; across file systems the move is a copy, so a full disk leaves a
truncated checkpoint under the final name and a multi-line ``OSError`` naming the temp file.
:class:`AtomicCheckpointIO` writes beside the target instead (temp file, fsync, rename): a
checkpoint is complete or absent, and a full disk is one line naming the checkpoint and the free
space. Remote paths (``s3://`` ...) keep Lightning's writer.
"""

from __future__ import annotations

from typing import Any

import torch
from lightning.pytorch.plugins.io import CheckpointIO, TorchCheckpointIO

from radar2shape.atomic import atomic_open

__all__ = ["AtomicCheckpointIO", "with_atomic_checkpoint_io"]


class AtomicCheckpointIO(TorchCheckpointIO):
    """``TorchCheckpointIO`` whose local saves go through the project's one atomic writer."""

    def save_checkpoint(self, checkpoint: dict[str, Any], path, storage_options: Any | None = None) -> None:
        if storage_options is not None or "://" in str(path):
            return super().save_checkpoint(checkpoint, path, storage_options)
        with atomic_open(path, "wb") as handle:
            torch.save(checkpoint, handle)


def with_atomic_checkpoint_io(plugins):
    """Trainer ``plugins`` plus an :class:`AtomicCheckpointIO`, unless they already name a CheckpointIO.

    For the Lightning CLI's trainer arguments: ``config["plugins"] = with_atomic_checkpoint_io(config.get("plugins"))``.
    """
    listed = [] if plugins is None else list(plugins) if isinstance(plugins, (list, tuple)) else [plugins]
    if any(isinstance(plugin, CheckpointIO) for plugin in listed):
        return listed
    return [*listed, AtomicCheckpointIO()]
