"""`radar2shape evaluate --up --normalise-gt`: a reconstruction (body frame, unit cube) against the
mesh it came from, as the user has it (metres, any up axis)."""

from __future__ import annotations

import numpy as np
import trimesh

from radar2shape.commands.evaluate import evaluate_files
from radar2shape.geometry.frames import to_body_frame
from radar2shape.geometry.normalise import normalisation


def test_a_reconstruction_scores_perfectly_against_its_y_up_source_in_metres(tmp_path):
    source = trimesh.creation.box(extents=(2.0, 4.0, 6.0))  # y up, metres, off centre
    source.apply_translation((10.0, 1.0, -3.0))
    source.export(tmp_path / "source.obj")
    body = to_body_frame(source, "y")
    centre, scale = normalisation(body.vertices)
    reconstruction = trimesh.Trimesh((body.vertices - centre) * scale, body.faces)  # what reconstruct writes
    reconstruction.export(tmp_path / "recon.obj")
    scores = evaluate_files(tmp_path / "recon.obj", tmp_path / "source.obj", 4000, 20000, normalise_gt=True, up="y")
    assert scores["iou"] > 0.99 and scores["chamfer_l2_x1e3"] < 1.0  # sampling noise of 4,000 points
    wrong_up = evaluate_files(tmp_path / "recon.obj", tmp_path / "source.obj", 4000, 20000, normalise_gt=True)
    assert wrong_up["iou"] < 0.8 and wrong_up["chamfer_l2_x1e3"] > 5.0  # the 4 m side lies along z only after --up y
    assert np.isclose(np.ptp(reconstruction.vertices, axis=0).max(), 1.0)
