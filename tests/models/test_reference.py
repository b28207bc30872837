"""Reference models: nearest-neighbour look-up by radar, majority-vote mean shape, and scoring by the callback."""

from __future__ import annotations

from pathlib import Path

import lightning as L
import numpy as np
import pytest
import torch
import trimesh

from data_modules.build import build_dataset
from data_modules.config import load_build_config
from data_modules.datamodules import ShapeDataModule
from data_modules.radar_transform import RadarTransform
from radar2shape.errors import UserInputError
from radar2shape.geometry.query import contains, sample_surface
from radar2shape.metrics import ReconstructionEvaluator, ShapeScorer
from radar2shape.models.reference import MeanShapeReference, NearestNeighbourReference
from radar2shape.radar import RadarGrid
from radar2shape.radar.spec import RadarSpec

REPO = Path(__file__).resolve().parents[2]


class RecordsStub:
    """What the references read from a DataModule: raw training records and the radar spec."""

    def __init__(self, meshes: list[trimesh.Trimesh], radars: list[np.ndarray] | None = None):
        radars = radars or [np.ones((2, 3, 4), np.complex64)] * len(meshes)
        self.records = [
            {"vertices": m.vertices, "faces": m.faces, "radar": r, "surface_points": sample_surface(m, 20000, 0)[0]}
            for m, r in zip(meshes, radars)
        ]

    def train_records(self):
        return self.records

    radar_spec = RadarSpec(RadarGrid(np.zeros(2), np.zeros(3), np.ones(4)), db_mean=-20.0, db_std=5.0)


def box(centre, extent=0.3) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=[extent] * 3, transform=trimesh.transformations.translation_matrix(centre))


def occupancy_iou(mesh: trimesh.Trimesh, truth: trimesh.Trimesh) -> float:
    points = np.random.default_rng(0).uniform(-0.55, 0.55, size=(20000, 3))
    a, b = contains(mesh, points), contains(truth, points)
    return float((a & b).sum() / (a | b).sum())


def test_mean_shape_is_the_majority_shape():
    left, right = box([-0.2, 0, 0]), box([0.2, 0, 0])
    reference = MeanShapeReference(resolution=32)
    reference.fit_reference(RecordsStub([left, left, right]))
    recs = reference.reconstruct({"radar": torch.zeros(3, 2, 3, 4)})
    assert len(recs) == 3
    assert occupancy_iou(recs[0].mesh, left) > 0.95
    assert occupancy_iou(recs[2].mesh, right) < 0.05


def test_nearest_neighbour_uses_only_observed_cells():
    rng = np.random.default_rng(0)
    radars = [(rng.normal(size=(2, 3, 4)) + 1j * rng.normal(size=(2, 3, 4))).astype(np.complex64) for _ in range(3)]
    stub = RecordsStub([box([x, 0, 0], 0.2) for x in (-0.3, 0.0, 0.3)], radars)
    reference = NearestNeighbourReference(chunk=2)  # several chunks
    reference.fit_reference(stub)
    full = RadarTransform(RecordsStub.radar_spec, observability="full")
    inputs = torch.from_numpy(np.stack([full(radars[i], rng, i)[0] for i in (2, 0, 1)]))
    mask = torch.ones(3, 2, 3, dtype=torch.bool)
    assert reference.neighbours(inputs, mask).tolist() == [2, 0, 1]
    # unobserved cells are ignored however wrong they are
    corrupted, mask[:, 0] = inputs.clone(), False
    corrupted[:, 0] = 100.0
    assert reference.neighbours(corrupted, mask).tolist() == [2, 0, 1]
    recs = reference.reconstruct({"radar": corrupted, "radar_mask": mask})
    np.testing.assert_allclose(recs[0].mesh.vertices, stub.records[2]["vertices"])
    with pytest.raises(UserInputError, match="differ"):
        reference.neighbours(torch.zeros(1, 2, 3, 5), torch.ones(1, 2, 3, dtype=torch.bool))


def test_references_need_training_records():
    with pytest.raises(UserInputError, match="train_records"):
        NearestNeighbourReference().fit_reference(None)
    with pytest.raises(RuntimeError, match="fit_reference"):
        MeanShapeReference().reconstruct({"radar": torch.zeros(1, 2, 3, 4)})


@pytest.fixture(scope="module")
def parts_root(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("parts") / "data"
    build_dataset(load_build_config(REPO / "conf/data/parts_tiny.yaml", num=5), root, progress=False)
    return root


@pytest.mark.parametrize("reference", [NearestNeighbourReference, MeanShapeReference])
def test_radar2shape_test_scores_references(parts_root, tmp_path, reference):
    """Through Trainer.test with the shared callback, like any model; a training shape finds itself."""
    points = {"surface": 256, "sdf": 256, "eval": 1024, "occ": 2048}
    datamodule = ShapeDataModule(str(parts_root), batch_size=2, points={s: points for s in ("train", "val", "test")})
    evaluator = ReconstructionEvaluator([ShapeScorer(1024)], num_saved=0)
    trainer = L.Trainer(logger=False, callbacks=[evaluator], enable_progress_bar=False, enable_model_summary=False,
                        accelerator="cpu", default_root_dir=tmp_path)
    model = reference()
    trainer.test(model, datamodule=datamodule, verbose=False)
    assert 0.0 <= evaluator.results["test"]["iou"]["mean"] <= 1.0
    if reference is NearestNeighbourReference:
        batch = next(iter(datamodule.train_dataloader()))  # random partial windows, no noise
        assert model.neighbours(batch["radar"], batch["radar_mask"]).tolist() == batch["index"].tolist()
