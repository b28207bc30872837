"""How many threads or processes the simulators use, in one place that both import."""

from __future__ import annotations

import os
import sys


def worker_count() -> int:
    """Threads for the chunk loop: torch's setting when torch is loaded, else the usable cores."""
    torch = sys.modules.get("torch")
    if torch is not None:
        return max(1, torch.get_num_threads())
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)
