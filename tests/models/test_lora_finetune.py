"""LoRA fine-tuning of a trained RadarDiffusion: starts equal, trains only adapters, reloads, merges."""

from __future__ import annotations

import pytest
import torch
from test_radar_diffusion import GRID, RadarStub, fit, radar_batch, sphere_batch, sphere_stage1, tiny_model

from radar2shape.errors import UserInputError
from radar2shape.models.lora_finetune import LoRARadarDiffusion
from radar2shape.models.radar_diffusion import RadarDiffusion


@pytest.fixture(autouse=True, scope="module")
def single_thread():
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A PO-trained stand-in: a tiny RadarDiffusion after two steps, saved by its Trainer."""
    root = tmp_path_factory.mktemp("lora")
    model = tiny_model(sphere_stage1(root / "stage1.ckpt"))
    trainer = fit(model, RadarStub(data(), GRID), 2, root)
    trainer.save_checkpoint(root / "base.ckpt")
    return model, str(root / "base.ckpt")


def data() -> dict:
    return {**radar_batch(4), "surface_points": sphere_batch()["surface_points"][:1].expand(4, -1, -1)}


def denoise(model, seed=1):
    gen = torch.Generator().manual_seed(seed)
    batch = radar_batch(2, seed)
    h_t = torch.randn(2, model.n_levels, model.latent_dim, generator=gen)
    with torch.no_grad():
        return model.eval()(batch["radar"], batch["radar_mask"], h_t, torch.tensor([10, 60]))


def randomise_adapters(model):
    with torch.no_grad():
        for name, p in model.named_parameters():
            if "lora_" in name:
                p.normal_(0.0, 0.2)


def test_starts_equal_to_the_base_and_trains_only_adapters(base, tmp_path):
    base_model, path = base
    model = LoRARadarDiffusion(base_ckpt=path, lora_rank=2, lora_alpha=4.0, lr=1e-2)
    torch.testing.assert_close(denoise(model), denoise(base_model), atol=0, rtol=0)
    trainable = {n for n, p in model.named_parameters() if p.requires_grad}
    assert trainable and all(".attn.q_proj.lora_" in n or ".attn.v_proj.lora_" in n for n in trainable)
    before = {n: p.detach().clone() for n, p in model.named_parameters()}
    fit(model, RadarStub(data(), GRID), 3, tmp_path)
    changed = {n for n, p in model.named_parameters() if not torch.equal(p, before[n])}
    assert changed and changed <= trainable


def test_checkpoint_reloads_without_the_base_and_merges(base, tmp_path):
    _, path = base
    model = LoRARadarDiffusion(base_ckpt=path, lora_rank=2)
    randomise_adapters(model)
    expected = denoise(model)
    torch.save({"state_dict": model.state_dict(), "hyper_parameters": dict(model.hparams),
                "pytorch-lightning_version": "2"}, tmp_path / "ft.ckpt")
    loaded = LoRARadarDiffusion.load_from_checkpoint(tmp_path / "ft.ckpt", map_location="cpu", weights_only=True)
    assert loaded.hparams.base_ckpt is None and loaded.hparams.base_source == path
    torch.testing.assert_close(denoise(loaded), expected, atol=0, rtol=0)
    plain_hparams = {k: v for k, v in model.hparams.items() if not k.startswith(("lora_", "base_"))}
    plain = RadarDiffusion(**plain_hparams)
    plain.load_state_dict(model.merged_state_dict())  # strict
    torch.testing.assert_close(denoise(plain), expected, atol=1e-5, rtol=0)


def test_bad_configuration(tmp_path):
    with pytest.raises(UserInputError, match="base_ckpt"):
        LoRARadarDiffusion()
    with pytest.raises(UserInputError, match="base_ckpt"):
        LoRARadarDiffusion(base_ckpt=str(tmp_path / "missing.ckpt"))


def test_cli_defaults_do_not_resize_the_base(base):
    """LightningCLI passes RadarDiffusion's defaults (dim 512, ...) through **hparams."""
    _, path = base
    model = LoRARadarDiffusion(base_ckpt=path, dim=512, n_layers=8, stage1_hparams=None, radar_meta=None)
    assert model.hparams.dim == 32 and model.hparams.radar_meta is not None
