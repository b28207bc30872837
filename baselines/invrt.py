"""InvRT baseline (Muthukrishnan et al., "InvRT: Solving Radar Inverse Problems with Transformers",
AAAI 2023): a Transformer encoder that regresses the roll-symmetric profile from the radar.

What we took from the paper, as far as it is known to us: the radar of a roll-symmetric object is
a sequence over aspect angle whose tokens are the per-aspect frequency responses; a Transformer
encoder with positional encoding reads the sequence, and the shape comes out in one forward pass
(no generative sampling). What we decided where the details are not available (docs/rollsym.md):
- token = one aspect's frequency vector (normalised dB) -> Linear to ``dim``, plus the
  sine-cosine encoding of the aspect index (``nn.positional``), the same code the diffusion
  models use for positions;
- unobserved aspects are removed as attention keys (key padding), so a masked aspect never
  influences the output, whatever value the DataModule wrote there;
- the output is read from ``P`` learned query tokens, one per profile point, appended to the
  sequence; each goes through a Linear to its normalised ``(r, z)``. Per-point queries keep the
  head small and let each point attend to the aspects that inform it (a DETR-style readout);
- loss: L1 on normalised profile coordinates (``loss="mse"`` available); same data, masks and
  noise augmentation as the diffusion model, since both read the same ProfileDataModule.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from radar2shape.models.profile_diffusion import ProfileModel
from radar2shape.nn.positional import sinusoidal_embedding
from radar2shape.nn.transformer import Transformer

LOSSES = {"l1": F.l1_loss, "mse": F.mse_loss}


class InvRT(ProfileModel):
    """Radar ``[B, A, F]`` (+ mask ``[B, A]``) -> profile ``[B, P, 2]`` by a Transformer encoder."""

    def __init__(
        self,
        num_aspect: int,
        num_freq: int,
        profile_points: int = 16,
        dim: int = 128,
        n_layers: int = 4,
        n_heads: int = 4,
        mlp_ratio: float = 4.0,
        dropout: float = 0.0,
        loss: str = "l1",
        lr: float = 1e-3,
        weight_decay: float = 0.01,
        mesh_segments: int = 64,
    ) -> None:
        super().__init__()
        if loss not in LOSSES:
            raise ValueError(f"loss: expected one of {sorted(LOSSES)}, got {loss!r}")
        self.save_hyperparameters()
        self.embed = nn.Linear(num_freq, dim)
        self.register_buffer("aspect_code", sinusoidal_embedding(torch.arange(num_aspect), dim), persistent=False)
        self.queries = nn.Parameter(0.02 * torch.randn(profile_points, dim))
        self.encoder = Transformer(dim, n_layers, n_heads, mlp_ratio, dropout)
        self.head = nn.Linear(dim, 2)

    def forward(self, radar: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Normalised profile ``[B, P, 2]`` from radar ``[B, A, F]`` and observed aspects ``mask [B, A]``."""
        b = radar.shape[0]
        tokens = torch.cat([self.embed(radar) + self.aspect_code, self.queries.expand(b, -1, -1)], dim=1)
        keys = torch.cat([mask, mask.new_ones(b, self.profile_points)], dim=1)  # queries are always keys
        allowed = keys[:, None, :].expand(b, tokens.shape[1], tokens.shape[1])
        out = self.encoder(tokens, attn_mask=allowed)
        return self.head(out[:, -self.profile_points :])

    def predict_normalised(self, batch: dict) -> torch.Tensor:
        channels = self.radar_input(batch)  # checked [B, F + 1, A]: radar zeroed where masked, then mask
        return self(channels[:, :-1].transpose(1, 2), channels[:, -1] > 0.5)

    def losses(self, batch: dict) -> dict[str, torch.Tensor]:
        return {"loss": LOSSES[self.hparams.loss](self.predict_normalised(batch), self.target_profiles(batch))}
