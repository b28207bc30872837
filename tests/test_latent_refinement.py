"""scripts/latent_refinement.py: fitted latents recover a known latent; one error line on bad input."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
import torch

from radar2shape.models.sdf_vae import SDFVAE, truncated_l1

REPO = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("latent_refinement", REPO / "scripts" / "latent_refinement.py")
latent_refinement = importlib.util.module_from_spec(spec)
spec.loader.exec_module(latent_refinement)

SMALL = dict(resolutions=[4, 8], hash_features=2, log2_hashmap_size=8, width=8, n_blocks=2, plane_channels=4,
             unet_channels=4, latent_dim=6, vae_hidden=8, mlp_hidden=16, mlp_layers=2, mesh_resolution=16)


def test_refinement_moves_a_perturbed_latent_towards_the_one_that_made_the_samples():
    # targets decoded from a known latent h*: from h* + noise, the fitted latent must lose most of
    # the loss and come closer to h*; the decoder's weights must not move
    torch.manual_seed(0)
    model = SDFVAE(**SMALL).eval().requires_grad_(False)
    for weight in model.decoder.parameters():  # a fresh decoder starts near a constant SDF
        weight.normal_(0.0, 0.5)
    weights = {k: v.clone() for k, v in model.state_dict().items()}
    target = torch.randn(2, 2, 6)
    points = torch.rand(2, 2000, 3) - 0.5
    with torch.no_grad():
        values = model.decode_sdf(target, points)
    start = target + 0.5 * torch.randn_like(target)
    fitted = latent_refinement.refine_latents(model, start, points, values, steps=300, lr=2e-2, batch_points=512)
    with torch.no_grad():
        before = truncated_l1(model.decode_sdf(start, points), values, model.hparams.truncation).item()
        after = truncated_l1(model.decode_sdf(fitted, points), values, model.hparams.truncation).item()
    assert after < 0.2 * before
    assert (fitted - target).norm() < (start - target).norm()
    assert all(torch.equal(v, model.state_dict()[k]) for k, v in weights.items())


def test_missing_checkpoint_is_one_error_line_and_no_output(tmp_path, monkeypatch):
    out = tmp_path / "r.md"
    monkeypatch.setattr(sys, "argv", ["latent_refinement.py", "--ckpt", str(tmp_path / "none.ckpt"),
                                      "--data", str(tmp_path), "--out", str(out)])
    with pytest.raises(SystemExit) as exc:
        latent_refinement.main()
    message = str(exc.value)
    assert message.startswith("error: ") and "none.ckpt not found" in message and "\n" not in message
    assert not out.exists() and not out.with_suffix(".csv").exists()
