"""HashEncoding against a brute-force per-point trilinear reference, on both storage paths."""

import itertools

import pytest
import torch

from radar2shape.nn import HashEncoding, spatial_hash


def brute_force(enc: HashEncoding, points: torch.Tensor) -> torch.Tensor:
    """Per point, per level: explicit trilinear blend of the 8 lattice vertices round it."""
    out = torch.zeros(len(points), enc.n_levels, enc.features_per_level, dtype=points.dtype)
    for n, p in enumerate(points):
        for level, res in enumerate(enc.resolutions):
            u = ((p + enc.bound) / (2 * enc.bound)).clamp(0, 1) * (res - 1)
            base = [min(int(torch.floor(c)), res - 2) for c in u]
            for corner in itertools.product((0, 1), repeat=3):
                w = 1.0
                for axis in range(3):
                    t = u[axis] - base[axis]
                    w = w * (t if corner[axis] else 1 - t)
                ijk = torch.tensor([base[a] + corner[a] for a in range(3)])
                out[n, level] += w * enc.vertex_features(level, ijk)
    return out


@pytest.fixture
def encoding() -> HashEncoding:
    torch.manual_seed(0)
    # T=9 (512 entries): 5^3 = 125 and 8^3 = 512 are dense, 9^3 and 17^3 are hashed.
    return HashEncoding([5, 8, 9, 17], features_per_level=3, log2_table_size=9, bound=0.55, init_scale=1.0)


def test_levels_use_the_expected_path(encoding):
    assert [encoding.is_dense(r) for r in encoding.resolutions] == [True, True, False, False]
    assert encoding.tables[0].shape == (3, 5, 5, 5)
    assert encoding.tables[2].shape == (512, 3)


def test_matches_brute_force_on_both_paths(encoding):
    points = torch.rand(64, 3, generator=torch.Generator().manual_seed(1)) * 1.2 - 0.6  # some outside
    points[0] = torch.tensor([0.55, 0.55, 0.55])  # upper corner: the last cell, weight 1
    points[1] = torch.tensor([-0.55, 0.0, 0.55])
    got = encoding(points)
    assert got.shape == (64, 4, 3)
    torch.testing.assert_close(got, brute_force(encoding, points), atol=1e-5, rtol=1e-5)


def test_batch_shape_and_gradients_reach_every_table(encoding):
    points = (torch.rand(2, 10, 3) - 0.5).requires_grad_()
    out = encoding(points)
    assert out.shape == (2, 10, 4, 3)
    out.square().sum().backward()
    assert all(t.grad is not None and t.grad.abs().sum() > 0 for t in encoding.tables)
    assert points.grad is not None and points.grad.abs().sum() > 0


def test_hashed_table_gradient_repeats_bit_for_bit_with_two_threads(encoding):
    """Many points share each of the 512 hashed entries; their gradient sums must not depend on
    which thread adds first (a training run must repeat at a fixed thread count)."""
    points = torch.rand(40_000, 3, generator=torch.Generator().manual_seed(2)) - 0.5
    weights = torch.randn(40_000, 4, 3, generator=torch.Generator().manual_seed(3))
    previous = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        grads = []
        for _ in range(4):
            encoding.zero_grad()
            (encoding(points) * weights).sum().backward()
            grads.append(encoding.tables[3].grad.clone())
    finally:
        torch.set_num_threads(previous)
    assert grads[0].abs().sum() > 0
    assert all(torch.equal(g, grads[0]) for g in grads[1:])


def test_interpolates_vertices_exactly(encoding):
    """At a lattice vertex the encoding returns that vertex's stored feature."""
    res = encoding.resolutions[3]
    ijk = torch.tensor([[3, 7, 11], [0, 0, 0], [16, 16, 16]])
    points = ijk.float() / (res - 1) * 2 * encoding.bound - encoding.bound
    torch.testing.assert_close(encoding(points)[:, 3], encoding.vertex_features(3, ijk), atol=1e-6, rtol=1e-6)


def test_spatial_hash_uses_instant_ngp_primes():
    ijk = torch.tensor([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
    expected = [1, 2654435761 % 2**19, 805459861 % 2**19, (1 ^ 2654435761 ^ 805459861) % 2**19]
    assert spatial_hash(ijk, 19).tolist() == expected


def test_rejects_lattice_smaller_than_one_cell():
    with pytest.raises(ValueError, match="resolutions"):
        HashEncoding([1, 4])
