"""Diffusion-SDF baseline: single-level Stage 1, all radar tokens visible, checkpoints, learning and overfitting."""

import numpy as np
import pytest
import torch
from baseline_data import RADAR_SHAPE, mean_scores, model_from_config, one_thread, shape_batch, train_steps, trainer_roundtrip

from baselines import DiffusionSDF
from radar2shape.errors import UserInputError
from radar2shape.models.sdf_vae import SDFVAE

STAGE1 = dict(resolutions=[8], hash_features=2, log2_hashmap_size=10, width=16, n_blocks=1, plane_channels=8,
              unet_channels=8, unet_max_depth=1, latent_dim=16, vae_hidden=8, mlp_hidden=32, mlp_layers=2, mesh_resolution=32)
STAGE2 = dict(num_freq=RADAR_SHAPE[-1], radar_blocks=2, dim=32, n_layers=2, n_heads=4, encoder_depth=18, encoder_width=0.125,
              num_steps=100, sample_steps=20, mesh_resolution=32)


@pytest.mark.parametrize("size", ["_tiny", pytest.param("", marks=pytest.mark.slow)])  # paper size: ~10 s
def test_config_files_build_both_stages(size, tmp_path):
    """conf/model/diffusion_sdf_vae{size}.yaml is a one-level SDFVAE; diffusion_sdf{size}.yaml loads its checkpoint."""
    import lightning as L

    stage1 = model_from_config(f"conf/model/diffusion_sdf_vae{size}.yaml")
    assert isinstance(stage1, SDFVAE) and stage1.n_levels == 1
    path = tmp_path / "stage1.ckpt"
    torch.save({"state_dict": stage1.state_dict(), "hyper_parameters": dict(stage1.hparams),
                "pytorch-lightning_version": L.__version__}, path)
    model = model_from_config(f"conf/model/diffusion_sdf{size}.yaml", stage1_ckpt=str(path))
    assert isinstance(model, DiffusionSDF) and model.hparams.stage1_hparams == dict(stage1.hparams)


@pytest.fixture(scope="module")
def batch():
    with one_thread():  # for every test of the module
        yield shape_batch(n_surface=512, n_sdf=1024)


def model_on(stage1: SDFVAE, **overrides) -> DiffusionSDF:
    torch.manual_seed(0)
    model = DiffusionSDF(stage1_hparams=dict(stage1.hparams), **{**STAGE2, **overrides})
    model.stage1.load_state_dict(stage1.state_dict())
    return model


def test_needs_a_single_level_stage1():
    with pytest.raises(UserInputError, match="single-level"):
        model_on(SDFVAE(**{**STAGE1, "resolutions": [4, 8]}))


def test_every_radar_block_conditions_the_one_latent():
    """No causal split: perturbing the first or the last frequency block both move the prediction."""
    model = model_on(SDFVAE(**STAGE1), radar_blocks=4).eval()
    with torch.no_grad():  # zero-initialised gates and heads would hide the radar at init
        for p in model.parameters():
            if not p.abs().sum():
                p.normal_(0.0, 0.3)
    gen = torch.Generator().manual_seed(0)
    radar, mask = torch.randn(2, *RADAR_SHAPE, generator=gen), torch.ones(2, *RADAR_SHAPE[:2], dtype=torch.bool)
    h, t = torch.randn(2, 1, 16, generator=gen), torch.tensor([10, 50])
    base = model(radar, mask, h, t)
    assert base.shape == (2, 1, 16)
    for block in (slice(0, 2), slice(6, 8)):
        moved = radar.clone()
        moved[..., block] += 3.0
        assert (model(moved, mask, h, t) - base).abs().max() > 1e-2


def test_checkpoint_holds_primitive_hyperparameters(batch, tmp_path):
    stage1 = SDFVAE(**STAGE1)
    model = model_on(stage1)
    model.standardiser.fit(torch.randn(8, 1, 16))
    loaded, one = trainer_roundtrip(model, batch, tmp_path)
    assert loaded.hparams.radar_blocks == 2 and loaded.hparams.stage1_hparams == dict(stage1.hparams)
    h, t = torch.zeros(1, 1, 16), torch.tensor([5])
    torch.testing.assert_close(loaded(one["radar"], one["radar_mask"], h, t), model(one["radar"], one["radar_mask"], h, t))


def test_latents_are_learned_from_radar(batch):
    """Fast learning test: eight radar fingerprints -> eight latents; 400 steps (~45 s on one core)
    bring the sampled latents to a relative MSE of ~0.4 (shuffled pairs: ~1.7)."""
    model = model_on(SDFVAE(**STAGE1), lr=1e-3)
    gen = torch.Generator().manual_seed(1)
    latents = 1.0 + 0.3 * torch.randn(8, 1, 16, generator=gen)
    model._train_latents = dict(enumerate(latents))
    model.standardiser.fit(latents)
    train_steps(model, batch, 400, loss_fn=model.diffusion_loss)
    samples = model.sample_latents(batch)[:, 0]
    relative_mse = float(((samples - latents) ** 2).mean() / latents.var(0).mean())
    shuffled = float(((samples - latents.roll(1, 0)) ** 2).mean() / latents.var(0).mean())
    assert relative_mse < 0.6 and relative_mse < 0.5 * shuffled, (relative_mse, shuffled)


@pytest.mark.slow
def test_overfits_eight_shapes(batch, tmp_path):
    """Stage 1 (one 16 px level, 400 steps) then Stage 2 (600 steps) on the eight shapes and their
    fingerprints; meshes by DDIM + marching cubes at 32^3. Budget: ~2.5 minutes on one core.
    Measured: Stage 1 autoencoding Chamfer x10^3 0.41, IoU 0.92, F@1% 0.43; radar -> shape 0.70, 0.86, 0.26."""
    torch.manual_seed(0)
    stage1 = SDFVAE(**{**STAGE1, "resolutions": [16], "log2_hashmap_size": 12, "width": 32, "unet_max_depth": 2,
                       "latent_dim": 32, "vae_hidden": 16, "mlp_hidden": 64}, lr=3e-3)
    train_steps(stage1, batch, 400)
    autoencoded = mean_scores(stage1, batch)
    model = model_on(stage1, dim=64, lr=1e-3)
    model._train_latents = dict(enumerate(stage1.encode(batch["surface_points"])[0].detach()))
    model.standardiser.fit(torch.stack(list(model._train_latents.values())))
    train_steps(model, batch, 600, loss_fn=model.diffusion_loss)
    scores = mean_scores(model, batch)
    print(f"stage 1 autoencoding {autoencoded}; radar -> shape {scores}")
    assert scores["iou"] > 0.75 and scores["chamfer_l2_x1e3"] < 1.5, (autoencoded, scores)
    assert np.isfinite(scores["fscore_1pct"])
