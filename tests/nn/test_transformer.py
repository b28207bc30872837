"""Attention projections, masking and conditioning of the Transformer."""

import torch
from torch import nn

from radar2shape.nn.positional import TimestepEmbedding, sinusoidal_embedding
from radar2shape.nn.transformer import Attention, Transformer, causal_mask


def randomise_modulation(model: nn.Module) -> None:
    """adaLN-Zero starts with zero gates; give them values so conditioning is visible."""
    gen = torch.Generator().manual_seed(0)
    for name, p in model.named_parameters():
        if "modulation" in name:
            p.data = 0.2 * torch.randn(p.shape, generator=gen)


def test_separate_qkv_projections_are_linear_layers():
    attn = Transformer(16, 2, 4, cond_dim=8).blocks[0].attn
    for name in ("q_proj", "k_proj", "v_proj", "out_proj"):
        assert isinstance(getattr(attn, name), nn.Linear)


def test_attention_matches_reference_softmax_with_mask():
    torch.manual_seed(0)
    attn = Attention(8, 2)
    x = torch.randn(3, 5, 8)
    mask = causal_mask(5)
    q, k, v = (p(x).reshape(3, 5, 2, 4).transpose(1, 2) for p in (attn.q_proj, attn.k_proj, attn.v_proj))
    scores = (q @ k.transpose(-1, -2) / 2.0).masked_fill(~mask, float("-inf"))
    expected = attn.out_proj((scores.softmax(-1) @ v).transpose(1, 2).flatten(2))
    torch.testing.assert_close(attn(x, mask), expected, rtol=1e-5, atol=1e-6)


def test_causal_mask_blocks_information_from_later_tokens():
    torch.manual_seed(0)
    model = Transformer(16, 3, 4, cond_dim=16).eval()
    randomise_modulation(model)
    x, cond = torch.randn(2, 6, 16), torch.randn(2, 16)
    base = model(x, cond, causal_mask(6))
    for j in range(6):
        changed = x.clone()
        changed[:, j] += torch.randn(2, 16)  # not a constant shift, which LayerNorm would remove
        diff = (model(changed, cond, causal_mask(6)) - base).abs().amax(dim=(0, 2))
        assert torch.all(diff[:j] == 0), f"token {j} leaked into earlier tokens"
        assert torch.all(diff[j:] > 1e-6), f"token {j} did not reach later tokens"


def test_conditioning_and_zero_init():
    torch.manual_seed(0)
    model = Transformer(16, 2, 4, cond_dim=16)
    x = torch.randn(2, 4, 16)
    # adaLN-Zero: every block starts as the identity, so only the final norm acts
    torch.testing.assert_close(model(x, torch.randn(2, 16)), nn.functional.layer_norm(x, (16,)))
    randomise_modulation(model)
    assert not torch.allclose(model(x, torch.zeros(2, 16)), model(x, torch.ones(2, 16)))
    assert Transformer(16, 1, 2)(x).shape == (2, 4, 16)  # unconditioned variant


def test_sinusoidal_embedding_and_timestep_embedding():
    emb = sinusoidal_embedding(torch.tensor([0, 3]), 8)
    torch.testing.assert_close(emb[0], torch.tensor([0.0] * 4 + [1.0] * 4))
    torch.testing.assert_close(emb[1, 0], torch.sin(torch.tensor(3.0)))
    assert sinusoidal_embedding(torch.arange(4), 7).shape == (4, 7)
    assert TimestepEmbedding(12)(torch.tensor([0, 999])).shape == (2, 12)
