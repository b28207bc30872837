"""Diffusion-SDF baseline (Chou et al. 2023, "Diffusion-SDF: Conditional Generative Modeling of
Signed Distance Functions"), conditioned on radar.

What separates it from Radar2Shape, and nothing else:
- Stage 1 is the project's triplane SDF-VAE with a single level (``SDFVAE(resolutions=[R])``,
  conf/model/diffusion_sdf_vae*.yaml): one latent per shape, no multiresolution hierarchy;
- Stage 2 denoises that one latent with the radar's tokens all visible: the sequence is
  ``r_0 .. r_{J-1}, h`` with full attention (no coarse-to-fine split, no causal mask), where the
  response is cut into ``radar_blocks = J`` frequency blocks by the same ResNet block encoder.

Everything else (latent standardisation, DDPM loss, DDIM/DDPM sampling, meshes through the frozen
VAE decoder, two-stage training with the Stage-1 checkpoint copied into this one) is inherited
from :class:`radar2shape.models.radar_diffusion.RadarDiffusion`, so the comparison isolates the
hierarchy and the causal conditioning.
"""

from __future__ import annotations

import torch

from radar2shape.errors import UserInputError
from radar2shape.models.radar_diffusion import RadarDiffusion
from radar2shape.nn.radar_encoder import RadarBlockEncoder


class DiffusionSDF(RadarDiffusion):
    """Single-latent radar-conditional latent diffusion.

    Args:
        radar_blocks: number J of frequency blocks, i.e. radar tokens (``num_freq`` divisible by J).
        **kwargs: the arguments of :class:`RadarDiffusion` (``stage1_ckpt`` must hold a one-level SDFVAE).
    """

    def __init__(self, radar_blocks: int = 4, **kwargs) -> None:
        super().__init__(**kwargs)
        if self.n_levels != 1:
            raise UserInputError(
                f"DiffusionSDF needs a single-level Stage-1 SDFVAE (resolutions: [R]), got {self.n_levels} levels; "
                "train it with conf/model/diffusion_sdf_vae.yaml"
            )
        hp = self.hparams
        self.radar_encoder = RadarBlockEncoder(hp.num_freq, int(radar_blocks), hp.dim, hp.encoder_depth, hp.encoder_width)
        self.attn_mask = None  # every token sees every other one

    def network_output(self, radar_tokens: torch.Tensor, h_t: torch.Tensor, t: torch.Tensor) -> torch.Tensor:
        """Output ``[B, 1, Z]`` at the shape token of the standardised noisy latent ``h_t [B, 1, Z]`` given radar tokens ``[B, J, D]``."""
        shape_token = self.latent_in(h_t) + self.token_type[1]
        tokens = torch.cat([radar_tokens, shape_token], dim=1)
        return self.latent_out(self.transformer(tokens, self.time_embed(t))[:, -1:])
