"""The base task: one set of Lightning steps, optimizers from hyperparameters, retired names refused."""

from __future__ import annotations

import lightning as L
import pytest
import torch

from baselines.tmnet import TMNet
from radar2shape.datamodule import ReconstructionDataModule
from radar2shape.errors import UserInputError
from radar2shape.models.profile_diffusion import ProfileUNetDiffusion
from radar2shape.models.reference import MeanShapeReference
from radar2shape.models.sdf_vae import SDFVAE
from radar2shape.toy import ToySphereDataModule, ToySphereRegressor
from tests.models.test_sdf_vae import TINY as TINY_VAE
from tests.models.test_sdf_vae import random_batch


def test_steps_log_every_loss_term_per_stage(tmp_path):
    """Validation/test log ``<stage>/<term>`` with the values ``losses`` gives on the whole split."""
    torch.manual_seed(0)
    data = ToySphereDataModule(num_train=16, num_val=8, batch_size=8, eval_points=16, occ_points=16)
    model = ToySphereRegressor()
    trainer = L.Trainer(max_epochs=2, logger=False, enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False, accelerator="cpu", default_root_dir=tmp_path)
    trainer.fit(model, data)
    val = trainer.callback_metrics
    assert {"train/loss_step", "train/loss_epoch", "train/radius_l1_epoch", "val/loss", "val/radius_l1"} <= set(val)
    model.eval()
    with torch.no_grad():
        expected = float(model.losses(next(iter(data.val_dataloader())))["radius_l1"])
    assert float(val["val/radius_l1"]) == pytest.approx(expected, rel=1e-5)
    assert float(val["val/loss"]) == pytest.approx(expected, rel=1e-5)
    tested = trainer.test(model, data, verbose=False)[0]
    assert tested["test/radius_l1"] == pytest.approx(expected, rel=1e-5)


def test_optimizer_and_schedule_come_from_hyperparameters():
    config = SDFVAE(**TINY_VAE, lr=0.01, weight_decay=0.1, lr_decay_steps=5, lr_decay=0.2).configure_optimizers()
    optimizer, scheduler = config["optimizer"], config["lr_scheduler"]["scheduler"]
    assert type(optimizer) is torch.optim.Adam
    assert optimizer.defaults["lr"] == 0.01 and optimizer.defaults["weight_decay"] == 0.1
    assert scheduler.step_size == 5 and scheduler.gamma == 0.2
    tmnet = TMNet(num_freq=4, feature_dim=8, encoder_width=0.125, sphere_level=1, mlp_hidden=8, mlp_layers=1, lr=0.02)
    assert type(tmnet.configure_optimizers()) is torch.optim.Adam
    profile = ProfileUNetDiffusion(num_aspect=8, num_freq=4, weight_decay=0.3).configure_optimizers()
    assert type(profile) is torch.optim.AdamW and profile.defaults["weight_decay"] == 0.3
    decayed = ProfileUNetDiffusion(num_aspect=8, num_freq=4, lr_decay_steps=7, lr_decay=0.25, ema_decay=0.9)
    scheduler = decayed.configure_optimizers()["lr_scheduler"]["scheduler"]
    assert scheduler.step_size == 7 and scheduler.gamma == 0.25


def test_sdf_vae_takes_the_base_weight_average():
    assert SDFVAE(**TINY_VAE, ema_decay=0.99).hparams.ema_decay == 0.99
    with pytest.raises(UserInputError, match=r"SDFVAE: ema_decay must be in \[0, 1\), got 1.5"):
        SDFVAE(**TINY_VAE, ema_decay=1.5).configure_callbacks()


def test_sdf_vae_evaluates_the_posterior_mean():
    """Training samples the posterior (losses vary); validation/test decode its mean (they repeat)."""
    torch.manual_seed(0)
    model = SDFVAE(**TINY_VAE, init_logvar=0.0)
    batch = random_batch()
    first, second = model.eval_losses(batch, 0), model.eval_losses(batch, 7)
    assert torch.equal(first["loss"], second["loss"]) and torch.equal(first["sdf_l1"], second["sdf_l1"])
    assert not torch.equal(model.losses(batch)["sdf_l1"], model.losses(batch)["sdf_l1"])


def test_checkpoint_with_retired_hyperparameter_names_is_refused(tmp_path):
    model = ToySphereRegressor()
    path = tmp_path / "old.ckpt"
    hparams = {"num_freq": 16, "hidden": 64, "lr": 3e-3}  # as saved before `hidden` became `mlp_hidden`
    torch.save({"state_dict": model.state_dict(), "hyper_parameters": hparams,
                "pytorch-lightning_version": L.__version__}, path)
    with pytest.raises(UserInputError, match=r"hidden \(now mlp_hidden\); retrain"):
        ToySphereRegressor.load_from_checkpoint(path, weights_only=True)


def test_model_that_trains_nothing_refuses_a_training_step():
    with pytest.raises(UserInputError, match="MeanShapeReference has nothing to train; run it with `radar2shape test`"):
        MeanShapeReference().training_step({"radar": torch.zeros(1, 2, 2, 2)}, 0)
    assert MeanShapeReference().configure_optimizers() is None


def test_datamodules_say_their_radar_spec():
    assert ReconstructionDataModule().radar_spec is None
    assert isinstance(ToySphereDataModule(), ReconstructionDataModule) and ToySphereDataModule().radar_spec is None
