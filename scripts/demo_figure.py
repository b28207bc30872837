"""The demo's picture: per test shape, its radar (dB), the ground truth and each model's reconstruction."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from radar2shape.metrics.render import depth_image
from radar2shape.radar import to_db

VIEW = (-55.0, 25.0)  # azimuth, elevation in degrees: front three-quarter


def _saved_reconstruction(run_dir: Path, index: int) -> np.ndarray | None:
    """Surface samples of the reconstruction the metric callback saved for test item ``index``."""
    import trimesh

    files = sorted(run_dir.glob(f"version_*/reconstructions/test/epoch_*/sample_{index:06d}.*"))
    meshes = [f for f in files if f.suffix in (".obj", ".ply")]
    if not meshes:
        return None
    loaded = trimesh.load(meshes[-1], force="mesh", process=False)
    if isinstance(loaded, trimesh.Trimesh) and len(loaded.faces):
        return np.asarray(loaded.sample(20000, seed=0))
    return np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))))


def write_figure(path: Path, data_root: Path, model_runs: dict[str, Path], count: int = 4) -> Path:
    """Rows: test shapes; columns: radar dB image (mid frequency), ground truth, then one per model."""
    from matplotlib.figure import Figure

    from data_modules.datamodules import ShapeDataModule

    records = ShapeDataModule(root=str(data_root)).records("test")
    count = min(count, len(records))
    columns = ["radar (dB, mid band)", "ground truth", *model_runs]
    fig = Figure(figsize=(2.3 * len(columns), 2.3 * count))
    axes = fig.subplots(count, len(columns), squeeze=False)
    for row in range(count):
        record = records[row]
        radar_db = to_db(record["radar"])
        axes[row, 0].imshow(radar_db[:, :, radar_db.shape[2] // 2], cmap="magma", aspect="auto")
        clouds = [record["eval_points"]] + [_saved_reconstruction(run, row) for run in model_runs.values()]
        for col, points in enumerate(clouds, start=1):
            if points is None or len(points) == 0:
                axes[row, col].text(0.5, 0.5, "not saved", ha="center", va="center")
            else:
                axes[row, col].imshow(depth_image(points, *VIEW), cmap="viridis", vmin=-0.6, vmax=0.6)
        for col, title in enumerate(columns):
            axes[row, col].set_xticks([])
            axes[row, col].set_yticks([])
            if row == 0:
                axes[0, col].set_title(title, fontsize=9)
        axes[row, 0].set_ylabel(str(record.get("class_name", f"test #{row}")), fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path
