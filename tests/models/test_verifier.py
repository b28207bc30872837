"""The candidate verifier: its features' closed-form values, that it learns a ranking, its file."""

from __future__ import annotations

import pytest
import torch

from radar2shape.errors import UserInputError
from radar2shape.models.verifier import (
    candidate_features, feature_names, fit_verifier, load_verifier, occupancy_iou,
    probe_points, save_verifier, score_candidates,
)
from tests.models.test_radar_diffusion import radar_batch, sphere_stage1, tiny_model


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield tiny_model(sphere_stage1(tmp_path_factory.mktemp("stage1") / "stage1.ckpt")).eval()
    torch.set_num_threads(threads)


def test_occupancy_iou_by_hand():
    a = torch.tensor([[True, True, False, False], [False, False, False, False]])
    b = torch.tensor([[True, False, True, False], [False, False, False, False]])
    assert occupancy_iou(a, b).tolist() == [pytest.approx(1 / 3), 0.0]  # 1 shared of 3; both empty: 0


def test_probe_points_fill_the_cube_and_repeat():
    p = probe_points(0.5, 4096)
    assert p.shape == (4096, 3) and p.abs().max() <= 0.5 and torch.equal(p, probe_points(0.5, 4096))
    assert abs(float(p.mean())) < 0.02 and float(p.var()) == pytest.approx(1 / 12, rel=0.05)  # uniform on [-.5, .5]


def radar_tokens(model) -> torch.Tensor:
    batch = radar_batch(1)
    return model.encode_radar(batch["radar"], batch["radar_mask"])


def sdf_latent(model, radius: float) -> torch.Tensor:
    """Not a trained latent: any latent works, the features only compare candidates."""
    torch.manual_seed(int(radius * 100))
    return torch.randn(model.n_levels, model.latent_dim) * radius


def test_identical_candidates_agree_fully(model):
    tokens = radar_tokens(model)
    latent = sdf_latent(model, 1.0)
    features = candidate_features(model, tokens, latent.expand(3, -1, -1).clone(), probe_points(0.55, 2048))
    names = feature_names(model.n_levels)
    assert features.shape == (3, len(names))
    column = dict(zip(names, features[0].tolist()))
    assert column["consensus"] == pytest.approx(1.0) and column["iou_with_mean"] == pytest.approx(1.0)
    assert column["log_volume_ratio"] == pytest.approx(0.0, abs=1e-6)
    for name in names:
        if name.startswith(("latent_distance", "log_denoise_ratio")):
            assert column[name] == pytest.approx(0.0, abs=1e-5), name
    assert torch.equal(features[0], features[2])  # same candidate, same noise draw: same row


def test_the_outlier_has_the_lowest_consensus(model):
    tokens = radar_tokens(model)
    probe = probe_points(0.55, 4096)
    common = sdf_latent(model, 1.0)
    latents = torch.stack([common, common + 0.01, common - 0.01, sdf_latent(model, 3.0)])
    features = candidate_features(model, tokens, latents, probe)
    names = feature_names(model.n_levels)
    consensus = features[:, names.index("consensus")]
    distance = features[:, [i for i, n in enumerate(names) if n.startswith("latent_distance")]]
    assert int(consensus.argmin()) == 3 and int(distance.sum(1).argmax()) == 3
    # the latent distances are relative to their mean over the candidates
    assert distance.mean(0).tolist() == pytest.approx([1.0] * model.n_levels, rel=1e-5)


def test_needs_two_candidates(model):
    tokens = radar_tokens(model)
    with pytest.raises(UserInputError, match="at least 2"):
        candidate_features(model, tokens, sdf_latent(model, 1.0)[None], probe_points(0.55, 64))


def synthetic_ranking(n_shapes: int, k: int, seed: int):
    """IoU = 0.5 + 0.3 * feature 0 - 0.2 * feature 1^2 + noise; other features are distractors."""
    g = torch.Generator().manual_seed(seed)
    features = torch.randn(n_shapes, k, 6, generator=g)
    iou = 0.5 + 0.3 * features[..., 0] - 0.2 * features[..., 1] ** 2 + 0.01 * torch.randn(n_shapes, k, generator=g)
    return features, iou


def test_verifier_learns_which_candidate_is_best():
    features, iou = synthetic_ranking(200, 8, 0)
    verifier = fit_verifier(features, iou, epochs=300)
    test_features, test_iou = synthetic_ranking(100, 8, 1)
    with torch.no_grad():
        pick = verifier(test_features).argmax(-1)
    chosen = test_iou.gather(1, pick[:, None]).squeeze(1)
    best, first = test_iou.max(1).values, test_iou[:, 0]
    # held-out shapes: the choice closes >= 80 % of the first-to-best gap (a random pick closes ~0)
    assert float((chosen - first).mean()) >= 0.8 * float((best - first).mean())


def test_verifier_file_round_trip_and_mismatch(tmp_path, model):
    names = feature_names(model.n_levels)
    features, iou = torch.randn(10, 4, len(names)), torch.rand(10, 4)
    verifier = fit_verifier(features, iou, epochs=5)
    path = tmp_path / "v.verifier.pt"
    save_verifier(verifier, path, model.n_levels, {"data": "test"})
    loaded = load_verifier(path, model.n_levels)
    with torch.no_grad():
        assert torch.equal(loaded(features), verifier(features))
    with pytest.raises(UserInputError, match="do not match this model"):
        load_verifier(path, model.n_levels + 1)
    # trained for K = 8: the same K loads, another K is refused (its features are relative to the K)
    save_verifier(verifier, path, model.n_levels, {"candidates": 8})
    assert isinstance(load_verifier(path, model.n_levels, 8), type(verifier))
    with pytest.raises(UserInputError, match="trained to choose among K = 8 candidates, not 16; use --candidates 8"):
        load_verifier(path, model.n_levels, 16)
    (tmp_path / "junk.pt").write_bytes(b"not a file")
    with pytest.raises(UserInputError, match="junk.pt: not a readable verifier file"):
        load_verifier(tmp_path / "junk.pt", model.n_levels)


def test_scores_follow_the_verifier_on_the_models_own_samples(model):
    names = feature_names(model.n_levels)
    column = names.index("log_volume_ratio")
    verifier = fit_verifier(torch.randn(4, 3, len(names)), torch.rand(4, 3), epochs=1)
    with torch.no_grad():  # a verifier that scores by volume alone
        for p in verifier.parameters():
            p.zero_()
        verifier.mean.zero_()
        verifier.std.fill_(1.0)
        verifier.net[0].weight[0, column] = 1.0
        verifier.net[0].bias[0] = 5.0  # SiLU nearly linear far from 0
        verifier.net[2].weight[0, 0] = 1.0
        verifier.net[4].weight[0, 0] = 1.0
    batch = {k: v[:1] for k, v in radar_batch(1).items()}
    latents, scores = score_candidates(model, verifier, batch, num_samples=4, sample_seed=3)
    samples = model.sample_latents(batch, num_samples=4, sample_seed=3)[0]
    assert torch.equal(latents, samples) and scores.shape == (4,)
    index = int(scores.argmax())
    volume = (model.sdf_function(samples)(probe_points(float(model.stage1.hparams.bound))) < 0).float().mean(1)
    assert index == int(volume.argmax())



def test_kept_candidates_are_the_best_scored_first_ties_by_index():
    from radar2shape.models.verifier import kept_candidates

    predicted = torch.tensor([0.2, 0.7, 0.5, 0.7, 0.1])
    assert kept_candidates(predicted, 3).tolist() == [1, 3, 2]  # 0.7 twice: the lower index first
    assert kept_candidates(predicted, 1).tolist() == [1] and kept_candidates(predicted, 5).tolist() == [1, 3, 2, 0, 4]
    for keep in (0, 6):
        with pytest.raises(UserInputError, match=f"keep: expected 1 to 5 of the K candidates, got {keep}"):
            kept_candidates(predicted, keep)
