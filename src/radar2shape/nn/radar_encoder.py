"""Radar encoder of Stage 2: each frequency block of the dB response becomes one token.

The response ``[B, A, R, F]`` is cut into ``L`` blocks along frequency (equal when ``L``
divides ``F``); block ``j`` is an aspect x roll image whose channels are its ``F / L``
frequencies plus one observability-mask channel (so the network can tell "unobserved" from
"0 dB after normalisation"). One ResNet, shared by all blocks, maps each image to a token; a
sine-cosine encoding of ``j`` tells the Transformer which band a token came from.

ResNet choices that differ from torchvision's ImageNet ResNet, and why:
- a 3x3 stride-1 stem without max-pooling: radar images are small (tens of cells per side),
  an ImageNet stem would shrink them 4x before the first block;
- GroupNorm instead of BatchNorm: the batch is a few shapes, blocks of one response must not
  share statistics (the causal split), and sampling must behave like training;
- the last norm of every residual branch starts at zero, so deep variants (152) start as identities.

GroupNorm normalises each image by its own statistics, which removes most of a block's overall
dB level and contrast, i.e. the RCS magnitude. A linear "level path" from the masked mean and
standard deviation of each input channel puts them back into the token: without it the
eight-shape overfit could not tell the two closest responses apart (torus vs sphere+box: latent
error 1.6 after 1000 steps; 0.05 with it; BatchNorm gave 0.03 but mixes the blocks of a batch).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from radar2shape.nn.positional import sinusoidal_embedding

# depth -> (block type, blocks per stage), He et al. 2016, Table 1.
RESNET_LAYOUTS = {
    18: ("basic", (2, 2, 2, 2)),
    34: ("basic", (3, 4, 6, 3)),
    50: ("bottleneck", (3, 4, 6, 3)),
    101: ("bottleneck", (3, 4, 23, 3)),
    152: ("bottleneck", (3, 8, 36, 3)),
}


PADDINGS = ("zeros", "circular")


class RollConv2d(nn.Conv2d):
    """A convolution that pads the last axis (roll, a full circle) by wrapping and the other with zeros.

    Roll is periodic: the cells at 0 and 360 - step degrees are neighbours, and zero padding puts a
    false edge between them. Parameters and their names are those of ``nn.Conv2d``.
    """

    def __init__(self, c_in: int, c_out: int, kernel_size: int, stride: int = 1, padding: int = 0, bias: bool = True):
        super().__init__(c_in, c_out, kernel_size, stride=stride, padding=(padding, 0), bias=bias)
        self.roll_padding = padding

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.roll_padding:
            x = F.pad(x, (self.roll_padding, self.roll_padding, 0, 0), mode="circular")
        return super().forward(x)


def conv(c_in: int, c_out: int, kernel_size: int, stride: int = 1, padding: int = 0, roll: str = "zeros") -> nn.Conv2d:
    """A bias-free convolution with zero padding, or wrapped along roll (:class:`RollConv2d`)."""
    kind = RollConv2d if roll == "circular" and padding else nn.Conv2d
    return kind(c_in, c_out, kernel_size, stride=stride, padding=padding, bias=False)


def group_norm(channels: int, zero_init: bool = False) -> nn.GroupNorm:
    """GroupNorm with up to 32 groups of at least 4 channels; ``zero_init`` zeroes its scale.

    At least 4 channels per group keeps the statistics defined when the feature map is 1 x 1.
    """
    norm = nn.GroupNorm(math.gcd(32, max(1, channels // 4)), channels)
    if zero_init:
        nn.init.zeros_(norm.weight)
    return norm


def shortcut(c_in: int, c_out: int, stride: int) -> nn.Module:
    """Identity when shapes match, else a strided 1x1 projection."""
    if stride == 1 and c_in == c_out:
        return nn.Identity()
    return nn.Sequential(nn.Conv2d(c_in, c_out, 1, stride=stride, bias=False), group_norm(c_out))


class BasicBlock(nn.Module):
    """Two 3x3 convolutions (ResNet-18/34); output width = ``width``."""

    expansion = 1

    def __init__(self, c_in: int, width: int, stride: int, roll: str = "zeros") -> None:
        super().__init__()
        self.branch = nn.Sequential(
            conv(c_in, width, 3, stride, 1, roll), group_norm(width), nn.ReLU(inplace=True),
            conv(width, width, 3, 1, 1, roll), group_norm(width, zero_init=True),
        )
        self.skip = shortcut(c_in, width, stride)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.branch(x) + self.skip(x))


class Bottleneck(nn.Module):
    """1x1 reduce, 3x3, 1x1 expand (ResNet-50/101/152); output width = ``4 * width``."""

    expansion = 4

    def __init__(self, c_in: int, width: int, stride: int, roll: str = "zeros") -> None:
        super().__init__()
        c_out = width * self.expansion
        self.branch = nn.Sequential(
            nn.Conv2d(c_in, width, 1, bias=False), group_norm(width), nn.ReLU(inplace=True),
            conv(width, width, 3, stride, 1, roll), group_norm(width), nn.ReLU(inplace=True),
            nn.Conv2d(width, c_out, 1, bias=False), group_norm(c_out, zero_init=True),
        )
        self.skip = shortcut(c_in, c_out, stride)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.branch(x) + self.skip(x))


class ResNetEncoder(nn.Module):
    """Image ``[B, C, H, W]`` -> vector ``[B, out_dim]`` with a ResNet of the given depth.

    Args:
        in_channels: image channels; out_dim: output width.
        depth: 18, 34 (basic blocks), 50, 101 or 152 (bottleneck blocks).
        width_mult: multiplies the stage widths 64/128/256/512 (1.0 = the standard ResNet;
            e.g. 0.125 gives 8/16/32/64 for a CPU-sized model).
        roll_padding: "zeros" or "circular" (the last image axis wraps: :class:`RollConv2d`).
        stem_stride: stride of the 3x3 stem (1 keeps the image's resolution for the first stage;
            2 halves each side, a quarter of the stem and first-stage work, the largest share).
    """

    def __init__(self, in_channels: int, out_dim: int, depth: int = 18, width_mult: float = 1.0,
                 roll_padding: str = "zeros", stem_stride: int = 1) -> None:
        super().__init__()
        if depth not in RESNET_LAYOUTS:
            raise ValueError(f"ResNet depth must be one of {sorted(RESNET_LAYOUTS)}, got {depth}")
        if roll_padding not in PADDINGS:
            raise ValueError(f"roll_padding must be one of {PADDINGS}, got {roll_padding!r}")
        if stem_stride not in (1, 2):
            raise ValueError(f"stem_stride must be 1 or 2, got {stem_stride}")
        kind, counts = RESNET_LAYOUTS[depth]
        block = BasicBlock if kind == "basic" else Bottleneck
        widths = [max(4, round(w * width_mult)) for w in (64, 128, 256, 512)]
        layers: list[nn.Module] = [
            conv(in_channels, widths[0], 3, stem_stride, 1, roll_padding), group_norm(widths[0]), nn.ReLU(inplace=True)
        ]
        c_in = widths[0]
        for stage, (width, count) in enumerate(zip(widths, counts)):
            for i in range(count):
                layers.append(block(c_in, width, stride=2 if stage > 0 and i == 0 else 1, roll=roll_padding))
                c_in = width * block.expansion
        self.features = nn.Sequential(*layers)
        self.head = nn.Linear(c_in, out_dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.head(self.features(x).mean(dim=(-2, -1)))


def block_frequency_index(n_freq: int, n_blocks: int) -> torch.Tensor:
    """``[L, ceil(F / L)]`` frequency indices of each block; ``F`` (one past the end) marks padding.

    Contiguous blocks as ``numpy.array_split`` cuts them: equal when ``L`` divides ``F`` (the
    paper's 64 frequencies in 4 blocks); otherwise the first ``F mod L`` blocks hold one more.
    """
    if not 1 <= n_blocks <= n_freq:
        raise ValueError(f"cannot split {n_freq} frequencies into {n_blocks} blocks")
    width = -(-n_freq // n_blocks)
    index = torch.full((n_blocks, width), n_freq, dtype=torch.long)
    start = 0
    for j in range(n_blocks):
        size = n_freq // n_blocks + (j < n_freq % n_blocks)
        index[j, :size] = torch.arange(start, start + size)
        start += size
    return index


class RadarBlockEncoder(nn.Module):
    """Radar ``[B, A, R, F]`` + mask ``[B, A, R]`` -> tokens ``[B, L, dim]``, one per frequency block.

    Token = ResNet(block image) + level path(masked mean, std per channel) + position of the block.
    Blocks are contiguous bands (:func:`block_frequency_index`); a block one frequency short gets
    a zero channel in its place.

    ``roll_padding="circular"`` wraps the ResNet's padding along roll (the 360-degree circle has no
    edge) and adds the cosine and sine of each cell's roll angle as two input channels: with no
    edge to locate them, features would otherwise be blind to where on the circle they are, and a
    turned object's response differs from the unturned one only by that position.
    """

    def __init__(self, n_freq: int, n_blocks: int, dim: int, depth: int = 18, width_mult: float = 1.0,
                 roll_padding: str = "zeros", stem_stride: int = 1) -> None:
        super().__init__()
        self.n_blocks = n_blocks
        self.dim = dim
        self.roll_channels = 2 if roll_padding == "circular" else 0
        self.register_buffer("freq_index", block_frequency_index(n_freq, n_blocks), persistent=False)
        channels = self.freq_index.shape[1]
        self.resnet = ResNetEncoder(channels + 1 + self.roll_channels, dim, depth, width_mult, roll_padding, stem_stride)
        self.level = nn.Linear(2 * channels, dim)  # masked mean and std of each channel

    def forward(self, radar: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        b, a, r, _ = radar.shape
        padded = torch.cat([radar, radar.new_zeros(b, a, r, 1)], dim=-1)
        blocks = padded[..., self.freq_index].permute(0, 3, 4, 1, 2)  # [B, L, F/L, A, R]
        weight = mask.to(radar.dtype)[:, None, None].expand(b, self.n_blocks, 1, a, r)
        parts = [blocks, weight]
        if self.roll_channels:
            angle = torch.arange(r, device=radar.device, dtype=radar.dtype) * (2 * math.pi / r)
            parts.append(torch.stack([angle.cos(), angle.sin()])[:, None].expand(b, self.n_blocks, 2, a, r))
        images = torch.cat(parts, dim=2).flatten(0, 1)  # [B*L, F/L + 1 (+ 2), A, R]
        tokens = self.resnet(images).reshape(b, self.n_blocks, self.dim)
        count = weight.sum(dim=(-2, -1)).clamp(min=1.0)
        mean = (blocks * weight).sum(dim=(-2, -1)) / count
        variance = ((blocks - mean[..., None, None]) ** 2 * weight).sum(dim=(-2, -1)) / count
        std = variance.clamp_min(1e-12).sqrt()  # finite gradient for constant or fully masked blocks
        position = sinusoidal_embedding(torch.arange(self.n_blocks, device=radar.device), self.dim)
        return tokens + self.level(torch.cat([mean, std], dim=-1)) + position.to(tokens.dtype)
