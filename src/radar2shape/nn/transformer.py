"""A pre-norm Transformer whose blocks are conditioned on a vector (the diffusion timestep).

Attention keeps separate ``q_proj``, ``k_proj`` and ``v_proj`` linear layers (no fused qkv) so
that LoRA can wrap the query and value projections by name (the paper's fine-tuning, docs/design.md section 2).
Conditioning is adaptive LayerNorm with zero-initialised gates (adaLN-Zero, Peebles & Xie 2023):
every block starts as the identity and the timestep scales/shifts every normalised activation,
which conditions more strongly than adding the embedding to the input tokens once.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F


def causal_mask(n: int, device: torch.device | None = None) -> torch.Tensor:
    """Lower-triangular ``[n, n]`` bool mask: token ``i`` may attend to tokens ``j <= i`` (True = allowed)."""
    return torch.ones(n, n, dtype=torch.bool, device=device).tril()


class Attention(nn.Module):
    """Multi-head scaled dot-product self-attention with separate q/k/v projections."""

    def __init__(self, dim: int, n_heads: int, dropout: float = 0.0) -> None:
        super().__init__()
        if dim % n_heads:
            raise ValueError(f"attention width {dim} is not divisible by n_heads={n_heads}")
        self.n_heads = n_heads
        self.dropout = dropout
        self.q_proj = nn.Linear(dim, dim)
        self.k_proj = nn.Linear(dim, dim)
        self.v_proj = nn.Linear(dim, dim)
        self.out_proj = nn.Linear(dim, dim)

    def _heads(self, x: torch.Tensor) -> torch.Tensor:
        b, n, d = x.shape
        return x.reshape(b, n, self.n_heads, d // self.n_heads).transpose(1, 2)

    def forward(self, x: torch.Tensor, attn_mask: torch.Tensor | None = None) -> torch.Tensor:
        """``x [B, N, D]``; ``attn_mask`` bool ``[N, N]`` or ``[B, N, N]``, True where attention is allowed."""
        if attn_mask is not None and attn_mask.dim() == 3:
            attn_mask = attn_mask[:, None]  # broadcast over heads
        q, k, v = (self._heads(proj(x)) for proj in (self.q_proj, self.k_proj, self.v_proj))
        out = F.scaled_dot_product_attention(
            q, k, v, attn_mask=attn_mask, dropout_p=self.dropout if self.training else 0.0
        )
        return self.out_proj(out.transpose(1, 2).flatten(2))


def zero_modulation(cond_dim: int, out_dim: int) -> nn.Sequential:
    """SiLU + Linear producing shifts/scales/gates, zero at init (adaLN-Zero)."""
    linear = nn.Linear(cond_dim, out_dim)
    nn.init.zeros_(linear.weight)
    nn.init.zeros_(linear.bias)
    return nn.Sequential(nn.SiLU(), linear)


class AdaLayerNorm(nn.Module):
    """LayerNorm whose scale and shift come from a conditioning vector (plain LayerNorm without one)."""

    def __init__(self, dim: int, conditioned: bool) -> None:
        super().__init__()
        self.norm = nn.LayerNorm(dim, elementwise_affine=not conditioned)

    def forward(self, x: torch.Tensor, shift: torch.Tensor | None, scale: torch.Tensor | None) -> torch.Tensor:
        x = self.norm(x)
        return x if shift is None else x * (1 + scale[:, None]) + shift[:, None]


class TransformerBlock(nn.Module):
    """``x + gate * attn(norm(x))``, then ``x + gate * mlp(norm(x))``; norms and gates from ``cond``."""

    def __init__(
        self, dim: int, n_heads: int, mlp_ratio: float = 4.0, dropout: float = 0.0, cond_dim: int | None = None
    ) -> None:
        super().__init__()
        self.norm1 = AdaLayerNorm(dim, cond_dim is not None)
        self.attn = Attention(dim, n_heads, dropout)
        self.norm2 = AdaLayerNorm(dim, cond_dim is not None)
        hidden = int(dim * mlp_ratio)
        self.mlp = nn.Sequential(nn.Linear(dim, hidden), nn.GELU(), nn.Dropout(dropout), nn.Linear(hidden, dim))
        self.modulation = None if cond_dim is None else zero_modulation(cond_dim, 6 * dim)

    def forward(self, x: torch.Tensor, cond: torch.Tensor | None = None, attn_mask: torch.Tensor | None = None):
        if self.modulation is None:
            shift1 = scale1 = shift2 = scale2 = None
            gate1 = gate2 = 1.0
        else:
            shift1, scale1, gate1, shift2, scale2, gate2 = self.modulation(cond).chunk(6, dim=-1)
            gate1, gate2 = gate1[:, None], gate2[:, None]
        x = x + gate1 * self.attn(self.norm1(x, shift1, scale1), attn_mask)
        return x + gate2 * self.mlp(self.norm2(x, shift2, scale2))


class Transformer(nn.Module):
    """A stack of pre-norm blocks plus a final (conditioned) LayerNorm: ``[B, N, D] -> [B, N, D]``.

    Args:
        dim: token width D; n_layers, n_heads: depth and heads; mlp_ratio: MLP hidden width / D.
        cond_dim: width of the conditioning vector (None: unconditioned, plain LayerNorms).
    """

    def __init__(
        self,
        dim: int,
        n_layers: int,
        n_heads: int,
        mlp_ratio: float = 4.0,
        dropout: float = 0.0,
        cond_dim: int | None = None,
    ) -> None:
        super().__init__()
        self.blocks = nn.ModuleList(
            TransformerBlock(dim, n_heads, mlp_ratio, dropout, cond_dim) for _ in range(n_layers)
        )
        self.norm_out = AdaLayerNorm(dim, cond_dim is not None)
        self.out_modulation = None if cond_dim is None else zero_modulation(cond_dim, 2 * dim)

    def forward(
        self, x: torch.Tensor, cond: torch.Tensor | None = None, attn_mask: torch.Tensor | None = None
    ) -> torch.Tensor:
        """``x [B, N, D]``, ``cond [B, cond_dim]``, ``attn_mask`` bool ``[N, N]`` (True = may attend)."""
        for block in self.blocks:
            x = block(x, cond, attn_mask)
        if self.out_modulation is None:
            return self.norm_out(x, None, None)
        shift, scale = self.out_modulation(cond).chunk(2, dim=-1)
        return self.norm_out(x, shift, scale)
