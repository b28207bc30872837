"""LoRA fine-tuning of a trained RadarDiffusion: starts equal, trains only adapters, reloads, merges."""

from __future__ import annotations

import pytest
import torch
from test_radar_diffusion import GRID, RadarStub, fit, radar_batch, single_thread, sphere_batch, sphere_stage1, tiny_model  # noqa: F401 (autouse fixture)

from radar2shape.errors import UserInputError
from radar2shape.models.lora_finetune import LoRARadarDiffusion
from radar2shape.models.radar_diffusion import RadarDiffusion


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
    base_model, path = base
    model = LoRARadarDiffusion(base_ckpt=path, dim=512, n_layers=8, stage1_hparams=None)
    assert model.hparams.dim == 32 and model.radar_spec == base_model.radar_spec is not None


def test_base_trained_through_the_cli_loads(base, tmp_path):
    """A checkpoint written by `radar2shape fit` carries LightningCLI's `_class_path` / `_instantiator`
    in its hyperparameters; they are not RadarDiffusion arguments."""
    _, path = base
    ckpt = torch.load(path, map_location="cpu", weights_only=True)
    ckpt["hyper_parameters"].update(_class_path="radar2shape.models.radar_diffusion.RadarDiffusion", _instantiator="x")
    torch.save(ckpt, tmp_path / "cli.ckpt")
    model = LoRARadarDiffusion(base_ckpt=str(tmp_path / "cli.ckpt"))
    assert not any(k.startswith("_") for k in model.hparams)
    torch.testing.assert_close(denoise(model), denoise(LoRARadarDiffusion(base_ckpt=path)), atol=0, rtol=0)


def test_built_by_the_cli_keeps_its_class_path(base):
    """`radar2shape test --ckpt_path LORA.ckpt` rebuilds the model from the checkpoint's hparams and
    needs LightningCLI's "_class_path" there (without it the CLI fails to parse them)."""
    from lightning.pytorch.core.mixins.hparams_mixin import _given_hyperparameters_context

    _, path = base
    given = {"_class_path": "radar2shape.models.lora_finetune.LoRARadarDiffusion", "base_ckpt": path, "lora_rank": 4}
    with _given_hyperparameters_context(hparams=given, instantiator="lightning.pytorch.cli.instantiate_module"):
        model = LoRARadarDiffusion(base_ckpt=path)
    assert model.hparams["_class_path"] == given["_class_path"]
    assert model.hparams.base_ckpt is None and model.hparams.stage1_hparams is not None
