"""Eight analytic shapes (tests/models/shapes.py) in the contract's batch keys, each with its own
radar "fingerprint", for the baselines' overfit and smoke tests.

The fingerprint is a fixed random dB-like image per shape, not a simulated response: an overfit
test asks whether radar -> shape can be memorised through each model's whole pipeline, and
simulating eight responses would cost more than the test's budget.
"""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np
import torch

from models.shapes import SHAPES, shape_record
from radar2shape.metrics import score_reconstruction

RADAR_SHAPE = (8, 8, 8)  # aspect, roll, frequency


@contextmanager
def one_thread():
    """Tiny models run fastest on one thread; two threads on a busy 2-core machine thrash."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(threads)


def shape_batch(n_surface: int = 1024, n_sdf: int = 4096, n_eval: int = 4096, n_occ: int = 20_000, seed: int = 0) -> dict:
    """One batch of all eight shapes with every key the baselines and the metric callback read."""
    records = [shape_record(name, seed + i, n_surface=max(n_surface, n_eval), n_sdf=n_sdf, n_occ=n_occ) for i, name in enumerate(SHAPES)]
    rng = np.random.default_rng(seed)
    batch = {
        "surface_points": [r["surface_points"][:n_surface] for r in records],
        "surface_normals": [r["surface_normals"][:n_surface] for r in records],
        "sdf_points": [r["sdf_points"] for r in records],
        "sdf_values": [r["sdf_values"] for r in records],
        "eval_points": [r["eval_points"][:n_eval] for r in records],
        "occ_points": [r["occ_points"] for r in records],
        "occ_inside": [r["occ_inside"] for r in records],
    }
    batch = {k: torch.from_numpy(np.stack(v)) for k, v in batch.items()}
    batch["radar"] = torch.from_numpy(rng.normal(size=(len(records), *RADAR_SHAPE)).astype(np.float32))
    batch["radar_mask"] = torch.ones(len(records), *RADAR_SHAPE[:2], dtype=torch.bool)
    batch["index"] = torch.arange(len(records))
    batch["label"] = torch.zeros(len(records), dtype=torch.long)
    return batch


def subset(batch: dict, rows: list[int]) -> dict:
    """The same keys for a subset of shapes."""
    return {k: v[rows] for k, v in batch.items()}


def train_steps(model, batch: dict, steps: int, loss_fn=None) -> list[float]:
    """Full-batch optimisation with the model's own optimiser; returns the loss per step."""
    optimizer = model.configure_optimizers()
    optimizer = optimizer["optimizer"] if isinstance(optimizer, dict) else optimizer
    loss_fn = loss_fn or (lambda b: model.losses(b)["loss"])
    model.train()
    history = []
    for _ in range(steps):
        optimizer.zero_grad()
        loss = loss_fn(batch)
        loss.backward()
        optimizer.step()
        history.append(float(loss.detach()))
    model.eval()
    return history


def mean_scores(model, batch: dict, n_points: int = 4096) -> dict[str, float]:
    """Metric-callback scores of ``model.reconstruct(batch)``, averaged over the shapes."""
    recs = model.reconstruct(batch)
    scores = [
        score_reconstruction(rec, batch["eval_points"][i].numpy(), batch["occ_points"][i].numpy(),
                             batch["occ_inside"][i].numpy(), n_points, seed=i)
        for i, rec in enumerate(recs)
    ]
    return {k: float(np.nanmean([s[k] for s in scores])) for k in scores[0]}


def trainer_roundtrip(model, batch: dict, root, steps: int = 1):
    """Fit ``steps`` steps with a Lightning Trainer, save a checkpoint, check that it loads with
    ``torch.load(weights_only=True)`` with the same hyperparameters; returns
    ``(type(model).load_from_checkpoint of it, the batch's first shape)``, both models in eval mode."""
    import lightning as L

    items = [{k: v[i] for k, v in batch.items()} for i in range(len(batch["index"]))]
    trainer = L.Trainer(max_steps=steps, logger=False, enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False, accelerator="cpu", default_root_dir=root)
    trainer.fit(model, torch.utils.data.DataLoader(items, batch_size=len(items)))
    path = root / "model.ckpt"
    trainer.save_checkpoint(path)
    torch.load(path, map_location="cpu", weights_only=True)
    loaded = type(model).load_from_checkpoint(path, map_location="cpu", weights_only=True)
    assert loaded.hparams == model.hparams
    model.eval()
    return loaded.eval(), subset(batch, [0])


def model_from_config(path: str, **overrides):
    """The model a config file (``conf/model/*.yaml``, relative to the repository) describes, built directly."""
    import importlib
    from pathlib import Path

    import yaml

    spec = yaml.safe_load((Path(__file__).resolve().parents[2] / path).read_text())
    module, _, name = spec["class_path"].rpartition(".")
    return getattr(importlib.import_module(module), name)(**{**spec["init_args"], **overrides})
