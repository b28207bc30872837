"""Neural building blocks shared by the models and the baselines."""

from radar2shape.nn.gaussian import gaussian_kl, reparameterize
from radar2shape.nn.hash_encoding import HashEncoding, spatial_hash
from radar2shape.nn.mlp import MLP
from radar2shape.nn.plane_vae import PlaneDecoder, PlanePosterior
from radar2shape.nn.point_blocks import LocalPoolPointNet, ResnetBlockFC
from radar2shape.nn.triplane import local_pool, plane_cell_index, project_to_planes, sample_planes, scatter_mean
from radar2shape.nn.triplane_vae import MultiresTriplaneDecoder, MultiresTriplaneEncoder, TriplaneVAESizes
from radar2shape.nn.unet2d import UNet2D, depth_for_resolution

__all__ = [
    "HashEncoding",
    "LocalPoolPointNet",
    "MLP",
    "MultiresTriplaneDecoder",
    "MultiresTriplaneEncoder",
    "PlaneDecoder",
    "PlanePosterior",
    "ResnetBlockFC",
    "TriplaneVAESizes",
    "UNet2D",
    "depth_for_resolution",
    "gaussian_kl",
    "local_pool",
    "plane_cell_index",
    "project_to_planes",
    "reparameterize",
    "sample_planes",
    "scatter_mean",
    "spatial_hash",
]
from radar2shape.nn.diffusion import GaussianDiffusion  # noqa: E402  (Stage 2)
from radar2shape.nn.positional import TimestepEmbedding, sinusoidal_embedding  # noqa: E402
from radar2shape.nn.radar_encoder import RadarBlockEncoder, ResNetEncoder  # noqa: E402
from radar2shape.nn.transformer import Transformer, causal_mask  # noqa: E402
__all__ += ["GaussianDiffusion", "RadarBlockEncoder", "ResNetEncoder", "TimestepEmbedding", "Transformer", "causal_mask", "sinusoidal_embedding"]  # noqa: E501
