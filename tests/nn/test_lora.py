"""LoRA on the Stage-2 Transformer's q/v projections: init, training, merge, state dicts."""

import pytest
import torch
from torch import nn

from radar2shape.nn.lora import (LoRALinear, apply_lora, load_base_state_dict, mark_only_lora_trainable,
                                 merge_lora)
from radar2shape.nn.transformer import Transformer, causal_mask


def model_and_inputs(seed=0):
    torch.manual_seed(seed)
    model = Transformer(16, 2, 4, cond_dim=8)
    for name, p in model.named_parameters():  # adaLN-Zero gates start at zero; make them matter
        if "modulation" in name:
            p.data = 0.2 * torch.randn(p.shape)
    x, cond = torch.randn(3, 6, 16), torch.randn(3, 8)
    return model.eval(), x, cond, causal_mask(6)


def test_apply_wraps_only_q_and_v_and_starts_equal_to_the_base():
    model, x, cond, mask = model_and_inputs()
    before = model(x, cond, mask)
    names = apply_lora(model, rank=4, alpha=8.0)
    assert names == [f"blocks.{i}.attn.{p}" for i in range(2) for p in ("q_proj", "v_proj")]
    assert all(isinstance(model.get_submodule(n), LoRALinear) for n in names)
    assert type(model.blocks[0].attn.k_proj) is nn.Linear
    assert torch.equal(model(x, cond, mask), before)
    assert apply_lora(model) == []  # already wrapped: nothing matches twice


def test_only_lora_parameters_change_during_training():
    model, x, cond, mask = model_and_inputs()
    apply_lora(model, rank=2, alpha=4.0, dropout=0.1)
    model.train()
    trainable = mark_only_lora_trainable(model)
    assert trainable == 2 * 2 * (2 * 16 + 16 * 2)  # layers x (q, v) x (A + B)
    before = {n: p.detach().clone() for n, p in model.named_parameters()}
    opt = torch.optim.AdamW(model.parameters(), lr=1e-2, weight_decay=0.1)
    target = torch.randn(3, 6, 16)
    for _ in range(4):
        opt.zero_grad()
        nn.functional.mse_loss(model(x, cond, mask), target).backward()
        opt.step()
    for name, p in model.named_parameters():
        changed = not torch.equal(p, before[name])
        assert changed == ("lora_" in name), name


def test_merge_reproduces_the_unmerged_model_and_loads_into_the_plain_one():
    model, x, cond, mask = model_and_inputs()
    plain = Transformer(16, 2, 4, cond_dim=8).eval()
    apply_lora(model, rank=4, alpha=8.0)
    with torch.no_grad():
        for name, p in model.named_parameters():
            if "lora_" in name:
                p.normal_(0.0, 0.3)
    unmerged = model(x, cond, mask)
    assert len(merge_lora(model)) == 4
    assert not any(isinstance(m, LoRALinear) for m in model.modules())
    torch.testing.assert_close(model(x, cond, mask), unmerged, atol=1e-5, rtol=0)
    plain.load_state_dict(model.state_dict())  # strict: same keys as the un-LoRA'd model
    torch.testing.assert_close(plain(x, cond, mask), unmerged, atol=1e-5, rtol=0)


def test_base_checkpoint_loads_into_the_wrapped_model():
    base, x, cond, mask = model_and_inputs(seed=1)
    expected = base(x, cond, mask)
    wrapped, *_ = model_and_inputs(seed=2)
    apply_lora(wrapped)
    load_base_state_dict(wrapped, base.state_dict())
    assert torch.equal(wrapped(x, cond, mask), expected)
    with pytest.raises(RuntimeError, match="unexpected"):
        load_base_state_dict(wrapped, {**base.state_dict(), "extra.weight": torch.zeros(1)})


def test_bad_rank():
    with pytest.raises(ValueError, match="rank"):
        LoRALinear(nn.Linear(4, 4), rank=0)
