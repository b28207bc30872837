"""The fast training kernels against the reference ops they replace (radar2shape.nn.kernels).

Each fast form is a refactor: same values and gradients in float32 up to rounding, on random
inputs; the reference is the op kept behind ``reference_path()``. Plus determinism of the fast
path at a fixed thread count and the opt-in bfloat16 switch staying off by default.
"""

import copy

import pytest
import torch

from baselines import LIST
from baselines.point_losses import chamfer_l2, nearest
from radar2shape.models.sdf_vae import SDFVAE
from radar2shape.nn import kernels, local_pool, plane_cell_index, project_to_planes
from radar2shape.nn.triplane import PlaneCells

TOL = dict(atol=1e-5, rtol=1e-5)
SMALL_SDF_VAE = dict(resolutions=[4, 8, 16], hash_features=2, log2_hashmap_size=10, width=16, n_blocks=3,
                     plane_channels=8, unet_channels=8, unet_max_depth=2, latent_dim=16, vae_hidden=8,
                     mlp_hidden=32, mlp_layers=2)


@pytest.fixture(autouse=True)
def two_threads():
    previous = torch.get_num_threads()
    torch.set_num_threads(2)
    yield
    torch.set_num_threads(previous)


def both_paths(fn, *inputs):
    """``fn(*inputs)`` and the gradients of its sum wrt ``inputs``, on the fast and the reference path."""
    results = []
    for reference in (False, True):
        leaves = [x.detach().clone().requires_grad_(x.is_floating_point()) for x in inputs]
        with kernels.reference_path(reference):
            out = fn(*leaves)
        out.sum().backward()
        results.append((out.detach(), [x.grad for x in leaves if x.requires_grad]))
    return results


def assert_same(fast, reference):
    torch.testing.assert_close(fast[0], reference[0], **TOL)
    for g_fast, g_ref in zip(fast[1], reference[1]):
        torch.testing.assert_close(g_fast, g_ref, **TOL)


@pytest.mark.parametrize("res", [2, 8, 32])
def test_plane_pooling_matches_the_per_plane_scatter(res):
    torch.manual_seed(res)
    points, feats = torch.rand(3, 500, 3) * 1.2 - 0.6, torch.randn(3, 500, 5)
    index = plane_cell_index(points, res, 0.55)
    weights = torch.randn(3, 500, 5)  # a non-uniform upstream gradient
    assert_same(*both_paths(lambda f: local_pool(f, index, res) * weights, feats))
    assert_same(*both_paths(lambda f: project_to_planes(f, index, res) * torch.arange(1.0, 6)[:, None, None], feats))
    cells = PlaneCells.from_index(index, res)  # shared cells give the same as computing them per call
    torch.testing.assert_close(local_pool(feats, index, res, cells), local_pool(feats, index, res))


def test_nearest_and_chamfer_match_the_dense_matrix():
    torch.manual_seed(0)
    a, b = torch.rand(4, 300, 3) - 0.5, torch.rand(4, 700, 3) - 0.5
    assert_same(*both_paths(lambda x, y: chamfer_l2(x, y), a, b))
    assert_same(*both_paths(lambda x, y: nearest(x, y)[0], a, b))
    with kernels.reference_path():
        reference_index = nearest(a, b)[1]
    assert torch.equal(nearest(a, b)[1], reference_index)


def test_list_sdf_matches_the_reference_context():
    torch.manual_seed(0)
    model = LIST(num_freq=8, feature_dim=32, encoder_width=0.125, coarse_points=64, cloud_dim=16, local_dim=8,
                 mlp_hidden=32, mlp_layers=2)
    radar, mask = torch.randn(2, 16, 32, 8), torch.ones(2, 16, 32, dtype=torch.bool)
    queries = torch.rand(2, 200, 3) - 0.5
    results = []
    for reference in (False, True):
        model.zero_grad()
        with kernels.reference_path(reference):
            sdf = model.sdf(model.context(radar, mask), queries)
        sdf.square().sum().backward()
        results.append((sdf.detach(), [p.grad.clone() for p in model.parameters() if p.grad is not None]))
    assert_same(*results)


def sdf_vae_batch() -> dict:
    queries = torch.rand(2, 256, 3) - 0.5
    surface = torch.rand(2, 400, 3) - 0.5
    return {"surface_points": surface, "sdf_points": queries, "sdf_values": queries.norm(dim=-1) - 0.3}


def test_sdf_vae_loss_and_gradients_match_the_reference():
    torch.manual_seed(0)
    model, batch = SDFVAE(**SMALL_SDF_VAE), sdf_vae_batch()
    results = []
    for reference in (False, True):
        model.zero_grad()
        with kernels.reference_path(reference):
            loss = model.losses(batch, sample=False)["loss"]
        loss.backward()
        results.append((loss.detach(), [p.grad.clone() for p in model.parameters()]))
    assert_same(*results)


def test_fused_optimizer_step_matches_the_per_parameter_step():
    torch.manual_seed(0)
    model = SDFVAE(**SMALL_SDF_VAE)
    grads = [torch.randn_like(p) for p in model.parameters()]
    stepped = []
    for reference in (False, True):
        copy_ = copy.deepcopy(model)
        with kernels.reference_path(reference):
            optimizer = copy_.configure_optimizers()
        assert bool(optimizer.defaults["fused"]) is not reference
        for _ in range(3):
            for p, g in zip(copy_.parameters(), grads):
                p.grad = g.clone()
            optimizer.step()
        stepped.append(list(copy_.parameters()))
    for p_fast, p_ref in zip(*stepped):
        torch.testing.assert_close(p_fast, p_ref, atol=1e-6, rtol=1e-5)


def test_fast_training_repeats_bit_for_bit_at_a_fixed_thread_count():
    batch = sdf_vae_batch()
    runs = []
    for _ in range(2):
        torch.manual_seed(0)
        model = SDFVAE(**SMALL_SDF_VAE)
        optimizer = model.configure_optimizers()
        for _ in range(2):
            loss = model.losses(batch)["loss"]
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        runs.append([p.detach().clone() for p in model.parameters()])
    assert all(torch.equal(p, q) for p, q in zip(*runs))


def test_bf16_autocast_is_opt_in():
    assert not torch.is_autocast_enabled("cpu")
    with kernels.training_autocast("cpu"):
        assert not torch.is_autocast_enabled("cpu")
    kernels.set_bf16_training(True)
    try:
        with kernels.training_autocast("cpu"):
            assert torch.is_autocast_enabled("cpu") == kernels.cpu_has_bf16()
        with kernels.reference_path(), kernels.training_autocast("cpu"):
            assert not torch.is_autocast_enabled("cpu")
    finally:
        kernels.set_bf16_training(False)


def test_training_step_keeps_the_trainers_autocast():
    """``precision: bf16-mixed`` opens autocast around the step; the model's own switch, off, must not close it."""
    from radar2shape.models.base import ReconstructionModel

    seen = []

    class Probe(ReconstructionModel):
        def losses(self, batch):
            seen.append((torch.is_autocast_enabled("cpu"), (batch["x"] @ batch["x"]).dtype))
            return {"loss": batch["x"].sum()}

        def _log_losses(self, *args):
            pass

    x = torch.ones(4, 4)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        Probe().training_step({"x": x}, 0)
    Probe().training_step({"x": x}, 0)
    assert seen == [(True, torch.bfloat16), (False, torch.float32)]
