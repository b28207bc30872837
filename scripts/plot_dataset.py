"""Figure: a grid of dataset shapes, each beside its radar response in dB.

    python scripts/plot_dataset.py DATA_DIR --out reports/figures/parts.png [--split train] [--num 10]

Picks the first record of each class (then more records) so every class appears; the radar
panel is the dB image over aspect x frequency at roll 0 (the roll-symmetric view).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from data_modules.datasets import RecordSet  # noqa: E402
from data_modules.manifest import read_manifest  # noqa: E402
from radar2shape.radar import to_db  # noqa: E402

_LIGHT = np.array([0.4, -0.5, 0.75]) / np.linalg.norm([0.4, -0.5, 0.75])


def pick(labels: list[int], num: int) -> list[int]:
    """Indices: one per class first, then the rest in order, ``num`` in all."""
    firsts = [labels.index(c) for c in sorted(set(labels))]
    rest = [i for i in range(len(labels)) if i not in firsts]
    return (firsts + rest)[:num]


def draw_mesh(ax, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Lambert-shaded triangles in the unit cube, seen from a fixed oblique view."""
    triangles = vertices[faces]
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    shade = 0.25 + 0.75 * np.clip(normals @ _LIGHT, 0, 1)
    ax.add_collection3d(Poly3DCollection(triangles, facecolors=plt.cm.Blues(0.35 + 0.6 * shade), linewidths=0))
    for set_lim in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        set_lim(-0.5, 0.5)
    ax.set_box_aspect((1, 1, 1), zoom=1.3)
    ax.view_init(elev=20, azim=-60)
    ax.set_axis_off()


def plot_dataset(root: Path, out: Path, split: str = "train", num: int = 10, floor_db: float = -100.0) -> Path:
    manifest = read_manifest(root)
    records = RecordSet(root, split, manifest["splits"][split])
    chosen = pick(manifest["labels"][split], num)
    cols = min(5, len(chosen))
    rows = -(-len(chosen) // cols)
    fig = plt.figure(figsize=(3.2 * cols, 5.6 * rows))
    grid = fig.add_gridspec(2 * rows, cols, height_ratios=[1.5, 1.0] * rows)
    for n, index in enumerate(chosen):
        record = records[index]
        row, col = divmod(n, cols)
        ax = fig.add_subplot(grid[2 * row, col], projection="3d")
        draw_mesh(ax, record["vertices"], record["faces"])
        ax.set_title(f"{record['class_name']} ({record['record_id']})", fontsize=9)
        ax = fig.add_subplot(grid[2 * row + 1, col])
        freq = record["freq_hz"] / 1e9
        aspect = np.degrees(record["aspect_rad"])
        image = ax.imshow(to_db(record["radar"][:, 0], floor_db), aspect="auto", origin="lower", cmap="viridis",
                          extent=[freq[0], freq[-1], aspect[0], aspect[-1]])
        ax.set_xlabel("frequency (GHz)", fontsize=8)
        ax.set_ylabel("aspect (deg)", fontsize=8)
        ax.tick_params(labelsize=7)
        fig.colorbar(image, ax=ax, label="dBsm").ax.tick_params(labelsize=7)
    fig.suptitle(f"{manifest['family']}: {split} shapes and radar (roll 0)", fontsize=11)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="dataset folder (build-data --out)")
    parser.add_argument("--out", type=Path, required=True, help="PNG to write")
    parser.add_argument("--split", default="train")
    parser.add_argument("--num", type=int, default=10, help="shapes to show")
    args = parser.parse_args()
    print(plot_dataset(args.root, args.out, args.split, args.num))


if __name__ == "__main__":
    main()
