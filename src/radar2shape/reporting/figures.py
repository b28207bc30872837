"""Figures several layouts draw: depth images of saved test reconstructions beside the ground truth,
read back through each run's saved test config.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from radar2shape.reporting.cells import Cell
from radar2shape.reporting.tables import Layout


VIEW = (-55.0, 25.0)  # azimuth, elevation in degrees: front three-quarter


def saved_reconstructions(run_dir: Path) -> dict[int, Path]:
    """Test reconstructions the metric callback saved (``sample_<index>.obj|.ply``), by record index."""
    found = {}
    for path in sorted(run_dir.glob("test/**/reconstructions/test/epoch_*/sample_*")):
        if path.suffix in (".obj", ".ply"):
            found[int(path.stem.split("_")[1])] = path
    return found


def load_points(path: Path, n: int = 4096, seed: int = 0) -> np.ndarray:
    """Surface samples of a saved mesh, or the saved point set."""
    import trimesh

    from radar2shape.geometry.query import sample_surface

    loaded = trimesh.load(path, process=False)
    if isinstance(loaded, trimesh.Trimesh) and len(loaded.faces):
        return sample_surface(loaded, n, seed)[0]
    return np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))))


def run_datamodule(run_dir: Path):
    """The DataModule of a run's saved test config, set up for ``test`` (None without a config)."""
    import importlib

    import yaml

    configs = sorted(run_dir.glob("test/**/config.yaml"))
    if not configs:
        return None
    spec = yaml.safe_load(configs[-1].read_text()).get("data") or {}
    module, _, cls = str(spec.get("class_path", "")).rpartition(".")
    if not module:
        return None
    datamodule = getattr(importlib.import_module(module), cls)(**(spec.get("init_args") or {}))
    datamodule.setup("test")
    return datamodule


def ground_truth(run_dir: Path, indices: list[int]) -> dict[int, np.ndarray]:
    """``eval_points`` of test records by index, from the DataModule of the run's saved test config."""
    datamodule = run_datamodule(run_dir)
    if datamodule is None:
        return {}
    wanted, found = set(indices), {}
    for batch in datamodule.test_dataloader():
        for i, points in zip(batch["index"].tolist(), batch["eval_points"].numpy()):
            if i in wanted:
                found[i] = points
        if len(found) == len(wanted):
            break
    return found


def depth_axis(ax, points: np.ndarray | None, view=VIEW) -> None:
    from radar2shape.metrics.render import depth_image

    if points is None or len(points) == 0:
        ax.text(0.5, 0.5, "not saved", ha="center", va="center")
    else:
        ax.imshow(depth_image(points, *view), cmap="viridis", vmin=-0.6, vmax=0.6)
    ax.set_xticks([])
    ax.set_yticks([])


def one_replicate_per_row(cells: list[Cell], layout: Layout, n_saved: dict[str, int]) -> list[Cell]:
    """One cell per table row: of a row's seed replicates (``-seed<k>``), the one that saved the most
    test reconstructions (the first on a tie), so that a figure shows each model once."""
    best: dict[str, Cell] = {}
    for c in cells:
        row = layout.split(c.name)["row"]
        if row not in best or n_saved[c.name] > n_saved[best[row].name]:
            best[row] = c
    return list(best.values())


ROW_LABEL_CHARS = 28  # a line of a 9-point row label that fits beside one 2-inch row of panels


def row_label(title: str, width: int = ROW_LABEL_CHARS) -> str:
    """A row title broken into lines of at most ``width`` characters (a word longer stays whole), so
    long model titles stack beside their row instead of running over the rows around it."""
    return textwrap.fill(title, width, break_long_words=False, break_on_hyphens=False)


def model_rows_figure(cells: list[Cell], layout: Layout, path: Path, n_shapes: int, title: str) -> Path | None:
    """Ground truth, then one row per model, for the first ``n_shapes`` test shapes the runs saved
    (seed replicates: see :func:`one_replicate_per_row`)."""
    from matplotlib.figure import Figure

    from radar2shape.metrics.render import VIEWS

    saved = {c.name: saved_reconstructions(c.run_dir) for c in cells}
    cells = one_replicate_per_row(cells, layout, {name: len(found) for name, found in saved.items()})
    indices = sorted(set().union(*saved.values()))[:n_shapes] if saved else []
    if not indices:
        return None
    rows = [("ground truth", ground_truth(cells[0].run_dir, indices))]
    rows += [(layout.row_title(layout.split(c.name)["row"]), {i: load_points(p) for i, p in saved[c.name].items()}) for c in cells]
    fig = Figure(figsize=(2.0 * len(indices) + 1.2, 2.0 * len(rows)))
    axes = fig.subplots(len(rows), len(indices), squeeze=False)
    for r, (label, points) in enumerate(rows):
        for c, index in enumerate(indices):
            depth_axis(axes[r, c], points.get(index, np.zeros((0, 3))), VIEWS[0])
            if r == 0:
                axes[r, c].set_title(f"test #{index}", fontsize=9)
            if c == 0:
                axes[r, c].set_ylabel(row_label(label), fontsize=9)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    return path


def radar_shapes_figure(cells: list[Cell], layout: Layout, path: Path, n_shapes: int) -> Path | None:
    """Rows: test shapes; columns: radar dB image (mid frequency), ground truth, then one per model."""
    from matplotlib.figure import Figure

    from radar2shape.radar import to_db

    datamodule = run_datamodule(cells[0].run_dir) if cells else None
    if datamodule is None:
        return None
    records = datamodule.records("test")
    count = min(n_shapes, len(records))
    saved = [saved_reconstructions(c.run_dir) for c in cells]
    columns = ["radar (dB, mid band)", "ground truth", *(layout.row_title(layout.split(c.name)["row"]) for c in cells)]
    fig = Figure(figsize=(2.3 * len(columns), 2.3 * count))
    axes = fig.subplots(count, len(columns), squeeze=False)
    for row in range(count):
        record = records[row]
        radar_db = to_db(record["radar"])
        axes[row, 0].imshow(radar_db[:, :, radar_db.shape[2] // 2], cmap="magma", aspect="auto")
        axes[row, 0].set_xticks([])
        axes[row, 0].set_yticks([])
        clouds = [record["eval_points"]] + [load_points(s[row], 20000) if row in s else None for s in saved]
        for col, points in enumerate(clouds, start=1):
            depth_axis(axes[row, col], points)
        axes[row, 0].set_ylabel(str(record.get("class_name", f"test #{row}")), fontsize=9)
    for col, title in enumerate(columns):
        axes[0, col].set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path
