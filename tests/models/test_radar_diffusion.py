"""Stage 2 (RadarDiffusion): causal information flow, fit-start statistics, checkpoints, sampling.

A tiny Stage-1 SDF-VAE fitted to a sphere in a few seconds stands in for a trained Stage 1, so
meshes are real without a long Stage-1 run. The full radar -> mesh overfit on eight shapes
(IoU >= 0.7) trains Stage 1 for real and is marked slow.
"""

from __future__ import annotations

import lightning as L
import numpy as np
import pytest
import torch

from radar2shape.errors import UserInputError
from radar2shape.models.radar_diffusion import RadarDiffusion, load_latent_cache
from radar2shape.models.sdf_vae import SDFVAE
from radar2shape.radar import RadarGrid
from radar2shape.radar.spec import RadarSpec

TINY_STAGE1 = dict(
    resolutions=[4, 8], hash_features=2, log2_hashmap_size=8, width=16, n_blocks=1, plane_channels=8,
    unet_channels=8, unet_max_depth=1, latent_dim=8, vae_hidden=8, mlp_hidden=32, mlp_layers=2, mesh_resolution=32,
)
TINY_STAGE2 = dict(
    dim=32, n_layers=2, n_heads=4, encoder_depth=18, encoder_width=0.125, num_steps=100, mesh_resolution=32
)


@pytest.fixture(autouse=True, scope="module")
def single_thread():
    """Tiny models run fastest on one thread, and 2 threads on a busy 2-core machine thrash."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def save_checkpoint(model: L.LightningModule, path) -> str:
    """A Lightning-format checkpoint without a Trainer (what load_from_checkpoint reads)."""
    torch.save({"state_dict": model.state_dict(), "hyper_parameters": dict(model.hparams),
                "pytorch-lightning_version": L.__version__}, path)
    return str(path)


def sphere_batch(n: int = 512, radius: float = 0.3) -> dict:
    gen = torch.Generator().manual_seed(0)
    surface = torch.randn(2, n, 3, generator=gen)
    queries = torch.rand(2, 2 * n, 3, generator=gen) * 1.1 - 0.55
    return {"surface_points": radius * surface / surface.norm(dim=-1, keepdim=True),
            "sdf_points": queries, "sdf_values": queries.norm(dim=-1) - radius}


def sphere_stage1(path) -> str:
    """A tiny Stage 1 that decodes (roughly) a sphere of radius 0.3 for any latent near its data."""
    torch.manual_seed(0)
    model = SDFVAE(**TINY_STAGE1, lr=1e-2)
    optimizer, batch = model.configure_optimizers(), sphere_batch()
    for _ in range(60):
        optimizer.zero_grad()
        model.losses(batch)["loss"].backward()
        optimizer.step()
    return save_checkpoint(model, path)


@pytest.fixture(scope="module")
def stage1_ckpt(tmp_path_factory) -> str:
    return sphere_stage1(tmp_path_factory.mktemp("stage1") / "stage1.ckpt")


def tiny_model(stage1_ckpt: str, **overrides) -> RadarDiffusion:
    torch.manual_seed(0)
    return RadarDiffusion(stage1_ckpt=stage1_ckpt, **{"num_freq": 8, **TINY_STAGE2, **overrides})


def radar_batch(n: int, seed: int = 0) -> dict:
    gen = torch.Generator().manual_seed(seed)
    return {"radar": torch.randn(n, 4, 8, 8, generator=gen), "radar_mask": torch.ones(n, 4, 8, dtype=torch.bool),
            "index": torch.arange(n)}


def fit_batch(n: int = 4) -> dict:
    """A training batch for the fit tests: random radar, one sphere's surface points for every shape."""
    return {**radar_batch(n), "surface_points": sphere_batch()["surface_points"][:1].expand(n, -1, -1)}


def test_causal_mask_blocks_later_tokens(stage1_ckpt):
    model = tiny_model(stage1_ckpt).eval()
    with torch.no_grad():  # undo the zero inits (output head, adaLN gates) so every path carries signal
        for name, p in model.named_parameters():
            if "latent_out" in name or "modulation" in name:
                p.normal_(0.0, 0.2)
    batch = radar_batch(2)
    h, t = torch.randn(2, 2, 8), torch.tensor([10, 60])
    base = model(batch["radar"], batch["radar_mask"], h, t)

    def changed_levels(radar, latents) -> list[bool]:
        diff = (model(radar, batch["radar_mask"], latents, t) - base).abs().amax(dim=(0, 2))
        return [bool(d > 1e-6) for d in diff]

    later_block = batch["radar"].clone()
    later_block[..., 4:] += torch.randn(2, 4, 8, 4)  # frequency block 1 -> token r_1
    assert changed_levels(later_block, h) == [False, True]
    first_block = batch["radar"].clone()
    first_block[..., :4] += torch.randn(2, 4, 8, 4)  # r_0 reaches h_0 and h_1
    assert changed_levels(first_block, h) == [True, True]
    fine = h.clone()
    fine[:, 1] += torch.randn(2, 8)  # h_1 must not reach h_0
    assert changed_levels(batch["radar"], fine) == [False, True]
    coarse = h.clone()
    coarse[:, 0] += torch.randn(2, 8)
    assert changed_levels(batch["radar"], coarse) == [True, True]


def test_eval_losses_repeat_per_batch_index(stage1_ckpt):
    """Validation noise is seeded by the batch index: the same every epoch, different across batches."""
    model = tiny_model(stage1_ckpt)
    with torch.no_grad():
        model.latent_out.weight.normal_(0.0, 0.2)  # a non-zero output, so the loss depends on the noise
    batch = dict(radar_batch(2), **{k: v for k, v in sphere_batch().items() if k == "surface_points"})
    with torch.no_grad():
        first, again, other = (model.eval_losses(batch, i)["loss"] for i in (3, 3, 4))
        training = model.losses(batch)["loss"]
    assert set(model.eval_losses(batch, 3)) == {"loss"}
    assert torch.equal(first, again) and not torch.equal(first, other) and not torch.equal(first, training)


def test_latents_are_learned_from_radar(stage1_ckpt, tmp_path):
    """Eight radar fingerprints -> eight latents (from a cache file): samples land on their own latent."""
    gen = torch.Generator().manual_seed(1)
    latents = 0.25 * torch.randn(8, 2, 8, generator=gen)
    cache = tmp_path / "latents.pt"
    torch.save({"mu": latents, "index": torch.arange(8)}, cache)
    model = tiny_model(stage1_ckpt, latent_cache=str(cache), lr=1e-3)
    model._train_latents = load_latent_cache(cache)
    model.standardiser.fit(latents)
    batch = radar_batch(8)
    optimizer = model.configure_optimizers()
    model.train()
    torch.manual_seed(0)
    for _ in range(500):
        optimizer.zero_grad()
        model.diffusion_loss(batch).backward()
        optimizer.step()
    model.eval()
    samples = model.sample_latents(batch, num_samples=2, steps=20)  # [8, 2, L, Z]
    relative_mse = float(((samples - latents[:, None]) ** 2).mean() / latents.var())
    nearest = torch.cdist(samples.flatten(2).transpose(0, 1), latents.flatten(1)[None]).argmin(-1)
    assert relative_mse < 0.3, relative_mse
    assert (nearest == torch.arange(8)).all(), nearest


def test_reconstruct_meshes_and_spread(stage1_ckpt):
    model = tiny_model(stage1_ckpt).eval()
    model.standardiser.fit(model.stage1.encode(sphere_batch()["surface_points"])[0])
    recs = model.reconstruct(radar_batch(2))
    assert len(recs) == 2 and all(len(r.mesh.faces) > 0 for r in recs)
    extent = recs[0].mesh.bounds[1] - recs[0].mesh.bounds[0]
    assert np.all(extent > 0.4) and np.all(extent < 0.8)  # the sphere Stage 1 was fitted to
    (recon, spread), = model.reconstruct_with_uncertainty(radar_batch(1), num_samples=3, steps=5)
    assert spread.shape == (len(recon.mesh.vertices),) and np.all(spread >= 0)
    (_, single), = model.reconstruct_with_uncertainty(radar_batch(1), num_samples=1, steps=5)
    assert np.all(single == 0)
    first = model.sample_latents(radar_batch(1), num_samples=2, steps=5, eta=1.0, sample_seed=3)
    torch.testing.assert_close(first, model.sample_latents(radar_batch(1), num_samples=2, steps=5, eta=1.0, sample_seed=3))


class RadarStub(L.LightningDataModule):
    """The pieces of a radar DataModule that RadarDiffusion reads: the radar spec and training batches."""

    def __init__(self, batch: dict, grid: dict, db_mean: float = -30.0, db_std: float = 10.0):
        super().__init__()
        self.radar_spec = RadarSpec(RadarGrid(grid["aspect_rad"], grid["roll_rad"], grid["freq_hz"]), db_mean, db_std)
        n = len(batch["radar"])
        self.items = [{k: v[i] for k, v in batch.items()} for i in range(n)]

    def train_dataloader(self):
        return torch.utils.data.DataLoader(self.items, batch_size=len(self.items))


GRID = {"aspect_rad": np.linspace(0, np.pi, 4), "roll_rad": np.linspace(0, 2 * np.pi, 8, endpoint=False),
        "freq_hz": np.linspace(8e9, 12e9, 8)}


def fit(model: RadarDiffusion, datamodule: L.LightningDataModule, steps: int, root) -> L.Trainer:
    trainer = L.Trainer(max_steps=steps, logger=False, enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False, accelerator="cpu", default_root_dir=root)
    trainer.fit(model, datamodule=datamodule)
    return trainer


def test_fit_start_stores_statistics_and_radar_grid(stage1_ckpt, tmp_path):
    model = tiny_model(stage1_ckpt)
    batch = fit_batch()
    trainer = fit(model, RadarStub(batch, GRID), 2, tmp_path)
    assert bool(model.standardiser.ready)
    assert model.radar_spec.db_std == 10.0 and model.radar_spec.grid.shape == (4, 8, 8)
    path = tmp_path / "stage2.ckpt"
    trainer.save_checkpoint(path)
    loaded = RadarDiffusion.load_from_checkpoint(path, map_location="cpu", weights_only=True)
    torch.testing.assert_close(loaded.standardiser.mean, model.standardiser.mean)
    torch.testing.assert_close(loaded.stage1.decoder.mlp.state_dict(), model.stage1.decoder.mlp.state_dict())
    assert loaded.radar_spec == model.radar_spec and "radar_meta" not in loaded.hparams
    assert not any(p.requires_grad for p in loaded.stage1.parameters())


def test_a_stage2_checkpoint_gives_its_stage1_to_a_new_stage2(stage1_ckpt, tmp_path):
    """stage1_ckpt may be a trained Stage 2: the new model starts from that Stage 1, weight for weight."""
    from radar2shape.models.radar_diffusion import load_stage1

    trained = tiny_model(stage1_ckpt)
    with torch.no_grad():  # a Stage 1 that differs from the file the first model read
        for p in trained.stage1.parameters():
            p.add_(torch.randn_like(p))
    stage2_path = save_checkpoint(trained, tmp_path / "stage2.ckpt")
    stage1 = load_stage1(stage2_path)
    assert dict(stage1.hparams) == dict(trained.hparams.stage1_hparams)
    state, expected = stage1.state_dict(), trained.stage1.state_dict()
    assert state.keys() == expected.keys() and all(torch.equal(v, expected[k]) for k, v in state.items())
    restarted = tiny_model(stage2_path)
    assert all(torch.equal(v, expected[k]) for k, v in restarted.stage1.state_dict().items())


def test_learning_rate_schedule_from_hyperparameters(stage1_ckpt):
    """lr_decay_steps / lr_decay give the step decay (rate 1e-3 -> 2.5e-4 after 3 steps at 0.25)."""
    config = tiny_model(stage1_ckpt, lr=1e-3, lr_decay_steps=3, lr_decay=0.25).configure_optimizers()
    optimizer, scheduler = config["optimizer"], config["lr_scheduler"]["scheduler"]
    for _ in range(3):
        optimizer.step()
        scheduler.step()
    assert optimizer.param_groups[0]["lr"] == pytest.approx(2.5e-4)
    assert isinstance(tiny_model(stage1_ckpt).configure_optimizers(), torch.optim.Optimizer)  # 0 steps: constant


def test_bad_configuration_is_reported(stage1_ckpt, tmp_path):
    with pytest.raises(UserInputError, match="stage1_ckpt"):
        RadarDiffusion(stage1_ckpt=str(tmp_path / "missing.ckpt"))
    with pytest.raises(ValueError, match="cannot split"):
        tiny_model(stage1_ckpt, num_freq=1)
    with pytest.raises(UserInputError, match="radar must be"):
        tiny_model(stage1_ckpt).encode_radar(torch.zeros(1, 4, 8, 6), torch.ones(1, 4, 8, dtype=torch.bool))


@pytest.mark.slow
def test_overfit_eight_shapes_from_their_radar(tmp_path):
    """Stage 1 and Stage 2 trained on eight analytic shapes with their PO radar: mean IoU >= 0.7.

    Budget: about 3 minutes on 2 busy CPU cores (Stage 1 ~1 min, Stage 2 800 steps ~1.5 min,
    meshes 2 s). Measured mean IoU over Stage-2 seeds 0/1/2 with the noise loss: 0.88, 0.84, 0.87
    (Stage 1 alone: 0.89); with the velocity loss (the default), seed 0: 0.877 (torus 0.785).
    """
    from models.shapes import SHAPES, AnalyticShapeDataset
    from radar2shape.geometry.marching_cubes import grid_points, sdf_grid_to_mesh
    from radar2shape.metrics import score_reconstruction
    from radar2shape.radar import simulate, to_db

    torch.manual_seed(0)
    shapes = AnalyticShapeDataset(list(SHAPES), n_surface=512, n_sdf=1024)
    stage1 = SDFVAE(**{**TINY_STAGE1, "resolutions": [8, 16], "log2_hashmap_size": 12, "width": 32, "unet_max_depth": 2,
                       "latent_dim": 16, "vae_hidden": 16, "mlp_hidden": 64, "mesh_resolution": 48}, lr=3e-3)
    optimizer = stage1.configure_optimizers()
    for _ in range(400):
        for batch in torch.utils.data.DataLoader(shapes, batch_size=8, shuffle=True):
            optimizer.zero_grad()
            stage1.losses(batch)["loss"].backward()
            optimizer.step()

    grid = {"aspect_rad": np.linspace(0, np.pi, 8), "roll_rad": np.linspace(0, 2 * np.pi, 8, endpoint=False),
            "freq_hz": np.linspace(8e9, 12e9, 8)}
    points = grid_points(48, (-0.55, 0.55)).astype(np.float64)
    meshes = [sdf_grid_to_mesh(sdf(points).reshape(48, 48, 48), (-0.55, 0.55)) for sdf in SHAPES.values()]
    db = np.stack([to_db(simulate(mesh, *grid.values())) for mesh in meshes])
    truth = shapes.eval_batch(n_eval=5000, n_occ=20000)
    batch = {"radar": torch.from_numpy(((db - db.mean()) / db.std()).astype(np.float32)),
             "radar_mask": torch.ones(8, 8, 8, dtype=torch.bool), "index": torch.arange(8),
             "surface_points": truth["surface_points"]}

    model = RadarDiffusion(stage1_ckpt=save_checkpoint(stage1, tmp_path / "stage1.ckpt"), num_freq=8, dim=64,
                           n_layers=2, n_heads=4, encoder_depth=18, encoder_width=0.125, num_steps=100, lr=1e-3,
                           mesh_resolution=48)
    fit(model, RadarStub(batch, grid, float(db.mean()), float(db.std())), 800, tmp_path)
    recs = model.eval().reconstruct(batch)
    ious = [score_reconstruction(rec, truth["eval_points"][i].numpy(), truth["occ_points"][i].numpy(),
                                 truth["occ_inside"][i].numpy(), 5000)["iou"] for i, rec in enumerate(recs)]
    print(f"eight-shape overfit: mean IoU {np.mean(ious):.3f}, per shape {np.round(ious, 3).tolist()}")
    assert np.mean(ious) >= 0.7, np.round(ious, 3)


def test_ceiling_decodes_the_stage1_posterior_means(stage1_ckpt):
    """The evaluator's Stage-1 ceiling: the true shapes' posterior means meshed as Stage 2 meshes its samples."""
    assert TINY_STAGE2["mesh_resolution"] == TINY_STAGE1["mesh_resolution"]  # the same grid on both sides
    model = tiny_model(stage1_ckpt).eval()
    batch = sphere_batch()
    ceiling = model.reconstruct_ceiling(batch)
    direct = model.stage1.reconstruct(batch)  # Stage 1 decoding its own posterior means
    assert len(ceiling) == 2
    for ours, theirs in zip(ceiling, direct):
        np.testing.assert_allclose(ours.mesh.bounds, theirs.mesh.bounds, atol=1e-5)
        assert len(ours.mesh.faces) == len(theirs.mesh.faces) > 0
    assert model.reconstruct_ceiling(radar_batch(2)) is None  # no surface points: no ceiling


def test_guidance_zero_ignores_the_radar_and_fully_masked_radar_has_finite_gradients(stage1_ckpt):
    model = tiny_model(stage1_ckpt, guidance=0.0).eval()
    model.standardiser.fit(model.stage1.encode(sphere_batch()["surface_points"])[0])
    with torch.no_grad():  # zero-initialised output and gates would make any output ignore the radar
        for param in [*model.transformer.parameters(), *model.latent_out.parameters()]:
            if not param.any():
                param.normal_(std=0.3)
    same = [model.sample_latents(radar_batch(2, seed), steps=4, sample_seed=1) for seed in (0, 1)]
    torch.testing.assert_close(same[0], same[1])
    model.hparams.guidance = 2.0
    assert not torch.allclose(model.sample_latents(radar_batch(2, 0), steps=4, sample_seed=1),
                              model.sample_latents(radar_batch(2, 1), steps=4, sample_seed=1))
    blank = radar_batch(2)
    tokens = model.encode_radar(torch.zeros_like(blank["radar"]).requires_grad_(), torch.zeros_like(blank["radar_mask"]))
    tokens.sum().backward()
    assert all(torch.isfinite(p.grad).all() for p in model.radar_encoder.parameters() if p.grad is not None)


class WeightTrajectory(L.Callback):
    """Records one weight after every optimizer step."""

    def __init__(self):
        self.values = []

    def on_train_batch_end(self, trainer, pl_module, outputs, batch, batch_idx):
        self.values.append(pl_module.latent_out.bias.detach().clone())


def test_ema_decay_leaves_the_exponential_average_of_the_weights(stage1_ckpt, tmp_path):
    """After fitting, the weights (and the checkpoint) are e_k = d e_(k-1) + (1 - d) w_k, e_1 = w_1."""
    batch = fit_batch()
    decay, steps = 0.8, 6
    model, trajectory = tiny_model(stage1_ckpt, ema_decay=decay, lr=1e-2), WeightTrajectory()
    trainer = L.Trainer(max_steps=steps, logger=False, enable_checkpointing=False, enable_progress_bar=False,
                        enable_model_summary=False, accelerator="cpu", default_root_dir=tmp_path,
                        callbacks=[trajectory])
    trainer.fit(model, datamodule=RadarStub(batch, GRID))
    assert len(trajectory.values) == steps
    expected = trajectory.values[0]
    for w in trajectory.values[1:]:
        expected = decay * expected + (1 - decay) * w
    assert not torch.allclose(expected, trajectory.values[-1], atol=1e-4)  # the average is not the last iterate
    torch.testing.assert_close(model.latent_out.bias, expected)
    trainer.save_checkpoint(tmp_path / "ema.ckpt")
    loaded = RadarDiffusion.load_from_checkpoint(tmp_path / "ema.ckpt", map_location="cpu", weights_only=True)
    torch.testing.assert_close(loaded.latent_out.bias, expected)


def test_ema_decay_out_of_range_is_refused(stage1_ckpt, tmp_path):
    batch = fit_batch()
    with pytest.raises(UserInputError, match="ema_decay must be in"):
        fit(tiny_model(stage1_ckpt, ema_decay=1.0), RadarStub(batch, GRID), 1, tmp_path)


def test_latent_cache_is_not_used_for_turned_samples(stage1_ckpt):
    """With roll augmentation a batch names its turn (``roll_turn``): the per-record cache holds each
    record in one pose, so turned samples are encoded afresh (else radar and latents disagree)."""
    model = tiny_model(stage1_ckpt).train()
    batch = {**radar_batch(2), "surface_points": sphere_batch()["surface_points"][:1].expand(2, -1, -1)}
    fresh = model.stage1.encode(batch["surface_points"])[0]
    model._train_latents = {0: torch.zeros_like(fresh[0]), 1: torch.zeros_like(fresh[0])}
    assert model.encode_shapes(batch).abs().max() == 0  # unturned: the cache
    torch.testing.assert_close(model.encode_shapes({**batch, "roll_turn": torch.tensor([3, 9])}), fresh)


def test_turned_latents_are_cached_per_record_and_turn(stage1_ckpt):
    """``cache_turned_latents``: a (record, roll_turn) pair is encoded once; another turn of the same
    record, or another record, is encoded from its own points; only the unseen rows reach Stage 1."""
    model = tiny_model(stage1_ckpt, cache_turned_latents=True).train()
    points = sphere_batch()["surface_points"]  # two different point sets
    encoded = []
    encode = model.stage1.encode
    model.stage1.encode = lambda p: encoded.append(p.shape[0]) or encode(p)
    assert (encode(points)[0][0] - encode(points)[0][1]).abs().max() > 1e-3  # so a cache hit is visible
    first = {"index": torch.tensor([0, 1]), "roll_turn": torch.tensor([3, 3]), "surface_points": points}
    torch.testing.assert_close(model.encode_shapes(first), encode(points)[0])
    swapped = {**first, "surface_points": points.flip(0)}  # same records and turns, other points
    torch.testing.assert_close(model.encode_shapes(swapped), encode(points)[0])  # the cached ones
    mixed = {"index": torch.tensor([0, 0]), "roll_turn": torch.tensor([3, 35]), "surface_points": points.flip(0)}
    out = model.encode_shapes(mixed)
    torch.testing.assert_close(out[0], encode(points)[0][0])  # seen: cached
    torch.testing.assert_close(out[1], encode(points.flip(0))[0][1])  # record 0 turned otherwise: fresh
    assert encoded == [2, 1]  # the first batch, then only the one unseen row
    assert sorted(model._turned_latents) == [(0, 3), (0, 35), (1, 3)]


def test_init_weights_starts_from_a_trained_model_and_is_not_needed_to_load(stage1_ckpt, tmp_path):
    source = tiny_model(stage1_ckpt)
    trainer = fit(source, RadarStub(fit_batch(), GRID), 2, tmp_path / "source")
    init = tmp_path / "source.ckpt"
    trainer.save_checkpoint(init)
    torch.manual_seed(1)  # another draw of the fresh weights, so a copy is visible
    started = RadarDiffusion(stage1_ckpt=stage1_ckpt, init_weights=str(init), **{"num_freq": 8, **TINY_STAGE2})
    for name, value in source.state_dict().items():
        torch.testing.assert_close(started.state_dict()[name], value, rtol=0, atol=0, msg=name)
    assert bool(started.standardiser.ready)  # the latent statistics come along
    saved = tmp_path / "started.ckpt"
    fit(started, RadarStub(fit_batch(), GRID), 1, tmp_path / "started").save_checkpoint(saved)
    init.unlink()  # the fine-tuned model's checkpoint loads without the file it started from
    loaded = RadarDiffusion.load_from_checkpoint(saved, map_location="cpu", weights_only=True)
    torch.testing.assert_close(loaded.latent_out.weight, started.latent_out.weight)
    with pytest.raises(UserInputError, match="init_weights: .* not found"):
        tiny_model(stage1_ckpt, init_weights=str(init))


def test_init_encoder_copies_the_radar_encoder_alone_and_zeroes_the_roll_angle_channels(stage1_ckpt, tmp_path):
    """A zero-padded source's encoder goes into a circular-padded model: every encoder weight copied,
    the stem's two roll-angle input channels at zero, the denoiser left as freshly drawn."""
    source = tiny_model(stage1_ckpt)
    with torch.no_grad():  # move every weight off its fresh draw, so a copy (or its absence) is visible
        for parameter in source.parameters():
            parameter.add_(torch.randn_like(parameter))
    path = save_checkpoint(source, tmp_path / "source.ckpt")
    started = tiny_model(stage1_ckpt, roll_padding="circular", init_encoder=path)
    fresh = tiny_model(stage1_ckpt, roll_padding="circular")
    copied = started.radar_encoder.state_dict()
    for name, value in source.radar_encoder.state_dict().items():
        if copied[name].shape == value.shape:
            torch.testing.assert_close(copied[name], value, rtol=0, atol=0, msg=name)
        else:  # the stem: [out, in + 2, k, k]
            assert copied[name].shape[1] == value.shape[1] + 2, name
            torch.testing.assert_close(copied[name][:, : value.shape[1]], value, rtol=0, atol=0)
            assert copied[name][:, value.shape[1]:].abs().max() == 0
    torch.testing.assert_close(started.latent_in.weight, fresh.latent_in.weight, rtol=0, atol=0)
    assert not torch.equal(started.latent_in.weight, source.latent_in.weight)
    with pytest.raises(UserInputError, match=r"init_encoder: .*radar_encoder\..* is \("):
        tiny_model(stage1_ckpt, roll_padding="circular", encoder_width=0.25, init_encoder=path)
    with pytest.raises(UserInputError, match="set one of them"):
        tiny_model(stage1_ckpt, init_encoder=path, init_weights=path)


def test_canonical_heading_trains_turned_radar_on_the_unturned_latents(stage1_ckpt):
    """``canonical_heading``: a turned sample's target is its record's unturned latent from the cache,
    whatever its turned points encode to; a record missing from the cache is one clear error."""
    model = tiny_model(stage1_ckpt, canonical_heading=True).train()
    points = sphere_batch()["surface_points"]
    latent = torch.full_like(model.stage1.encode(points)[0][0], 0.5)
    model._train_latents = {0: latent, 1: -latent}
    batch = {"index": torch.tensor([1, 0]), "roll_turn": torch.tensor([5, 40]), "surface_points": points}
    torch.testing.assert_close(model.encode_shapes(batch), torch.stack([-latent, latent]))
    with pytest.raises(UserInputError, match="canonical_heading: a training record has no cached unturned latent"):
        model.encode_shapes({**batch, "index": torch.tensor([1, 7])})
    with pytest.raises(UserInputError, match="contradicts"):
        tiny_model(stage1_ckpt, canonical_heading=True, cache_turned_latents=True)


@pytest.mark.parametrize("options", [{"canonical_heading": True}, {"canonical_classes": ["jet"]}])
def test_place_in_heading_turns_the_mesh_into_the_observed_heading(stage1_ckpt, options):
    """The observed radar is an L-shaped solid's PO response turned by (3 steps, mirrored): the
    canonical mesh placed by the model is that solid turned the same way and scaled to its longest
    side (vertex for vertex), also where only some classes are learned canonical (the class is not
    known at test time)."""
    import trimesh

    from data_modules.augment import turn_and_mirror
    from radar2shape.radar import simulate
    from radar2shape.radar.heading import turn_rotation

    long = trimesh.creation.box((0.8, 0.15, 0.1))
    foot = trimesh.creation.box((0.15, 0.35, 0.1), trimesh.transformations.translation_matrix((0.325, 0.25, 0.0)))
    mesh = trimesh.util.concatenate([long, foot])
    model = tiny_model(stage1_ckpt, **options).eval()
    model.set_radar_spec(RadarStub(radar_batch(1), GRID).radar_spec)
    grid = model.radar_spec.grid
    response = simulate(mesh, grid.aspect_rad, grid.roll_rad, grid.freq_hz)  # size_m 1: the mesh as it is
    observed = turn_and_mirror({"radar": model.radar_spec.to_db(response)}, 3, True, roll_rad=grid.roll_rad)["radar"]
    batch = {"radar": torch.as_tensor(model.radar_spec.normalise(observed))[None],
             "radar_mask": torch.ones(1, 4, 8, dtype=torch.bool)}
    placed = model.place_in_heading(mesh, batch, 0)
    # atol: the sub-step refinement reads the equal neighbouring correlations to float precision
    turned = trimesh.Trimesh(mesh.vertices @ turn_rotation(8, 3, True).T, mesh.faces[:, ::-1], process=False)
    longest = np.ptp(mesh.vertices, axis=0).max()  # the frame of the observed heading: turned and scaled about
    ratio = longest / np.ptp(turned.vertices, axis=0).max()  # the origin to the same longest side
    np.testing.assert_allclose(placed.vertices, ratio * turned.vertices, atol=1e-6)
    assert placed.volume > 0  # still outward after the mirror
    assert tiny_model(stage1_ckpt).place_in_heading(mesh, batch, 0) is mesh  # other models: as it is


class TurnedRadarStub(RadarStub):
    """A stub whose training items are turned (``roll_turn``), which also serves them unturned and
    names its classes."""

    class_names = ["car", "jet"]

    def __init__(self, batch: dict, grid: dict, turns: list[int]):
        super().__init__(batch, grid)
        self.plain = [dict(item) for item in self.items]
        for item, turn in zip(self.items, turns):
            item["roll_turn"] = torch.tensor(turn)

    def unturned_train_dataloader(self):
        return torch.utils.data.DataLoader(self.plain, batch_size=len(self.plain))

    def labels_of(self, field, names):
        unknown = [name for name in names if name not in self.class_names]
        if unknown:
            raise UserInputError(f"{field}: unknown class(es) {unknown}")
        return [self.class_names.index(name) for name in names]


def test_canonical_classes_train_those_classes_on_unturned_latents_and_the_rest_turned(stage1_ckpt, tmp_path):
    """``canonical_classes``: a turned sample of a named class targets its record's unturned latent,
    one of another class the latent of its turned points; the names map to the data's labels at fit
    start (an unknown one is one error); it contradicts canonical_heading."""
    model = tiny_model(stage1_ckpt, canonical_classes=["jet"]).train()
    points = sphere_batch()["surface_points"] * torch.tensor([1.0, 0.6, 0.8])
    unturned = torch.full_like(model.stage1.encode(points)[0][0], 0.5)
    model._train_latents = {0: unturned, 1: -unturned}
    model._canonical_labels = frozenset({2})
    batch = {"index": torch.tensor([0, 1]), "label": torch.tensor([2, 5]), "roll_turn": torch.tensor([3, 9]),
             "surface_points": points}
    targets = model.encode_shapes(batch)
    torch.testing.assert_close(targets[0], unturned)
    torch.testing.assert_close(targets[1], model.stage1.encode(points)[0][1])
    with pytest.raises(UserInputError, match="canonical_classes: a training record has no cached unturned latent"):
        model.encode_shapes({**batch, "index": torch.tensor([7, 1])})

    data = {**fit_batch(2), "label": torch.tensor([1, 0])}
    fitted = tiny_model(stage1_ckpt, canonical_classes=["jet"])
    fit(fitted, TurnedRadarStub(data, GRID, turns=[3, 9]), 1, tmp_path / "a")
    assert fitted._canonical_labels == frozenset({1}) and sorted(fitted._train_latents) == [0, 1]
    with pytest.raises(UserInputError, match=r"canonical_classes: unknown class\(es\) \['ship'\]"):
        fit(tiny_model(stage1_ckpt, canonical_classes=["ship"]), TurnedRadarStub(data, GRID, turns=[3, 9]), 1, tmp_path / "b")
    with pytest.raises(UserInputError, match="canonical_classes names the classes that are"):
        tiny_model(stage1_ckpt, canonical_classes=["jet"], canonical_heading=True)
