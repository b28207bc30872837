"""A quick-look PNG of a response: dB aspect x roll images per frequency block and aspect cuts.

Uses matplotlib's object API with the Agg canvas, so it never touches pyplot's global state.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from radar2shape.atomic import atomic_path
from radar2shape.radar.signal import to_db


def plot_response(path: str | Path, response: np.ndarray, aspect_rad, roll_rad, freq_hz,
                  n_blocks: int = 4, title: str | None = None) -> Path:
    """Write a PNG: one image per frequency block (mean power in dBsm) and a cut at roll[0]."""
    response = np.asarray(response)
    aspect, roll, freq = np.degrees(aspect_rad), np.degrees(roll_rad), np.asarray(freq_hz) / 1e9
    blocks = np.array_split(np.arange(len(freq)), min(n_blocks, len(freq)))
    power_db = [10 * np.log10(np.maximum((np.abs(response[..., b]) ** 2).mean(axis=-1), 1e-20)) for b in blocks]
    vmax = max(float(p.max()) for p in power_db)
    fig = Figure(figsize=(3.2 * (len(blocks) + 1), 3.4), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(blocks) + 1)
    extent = (roll[0], roll[-1], aspect[-1], aspect[0])
    for ax, b, p in zip(axes, blocks, power_db):
        im = ax.imshow(p, aspect="auto", extent=extent, vmin=vmax - 60, vmax=vmax, cmap="viridis")
        ax.set(title=f"{freq[b[0]]:.3g}-{freq[b[-1]]:.3g} GHz", xlabel="roll (deg)", ylabel="aspect (deg)")
    fig.colorbar(im, ax=axes[:-1], label="dBsm", shrink=0.9)
    cut = axes[-1]
    for i in sorted({0, len(freq) // 2, len(freq) - 1}):
        cut.plot(aspect, to_db(response[:, 0, i]), label=f"{freq[i]:.3g} GHz")
    cut.set(title=f"cut at roll {roll[0]:.3g} deg", xlabel="aspect (deg)", ylabel="dBsm")
    cut.legend(fontsize="small")
    if title:
        fig.suptitle(title)
    path = Path(path)
    with atomic_path(path) as temp:  # the format follows the suffix, which the temp name keeps
        fig.savefig(temp, dpi=100)
    return path
