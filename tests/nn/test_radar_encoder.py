"""ResNet layouts, per-block independence and the mask channel of the radar encoder."""

import pytest
import torch

from radar2shape.nn.radar_encoder import (
    RESNET_LAYOUTS,
    Bottleneck,
    RadarBlockEncoder,
    ResNetEncoder,
    block_frequency_index,
)


@pytest.mark.parametrize("depth", [18, 34, 50, 101, 152])
def test_resnet_depths_build_with_expected_block_counts(depth):
    net = ResNetEncoder(3, 10, depth=depth, width_mult=1 / 16)
    kind, counts = RESNET_LAYOUTS[depth]
    blocks = [m for m in net.features if hasattr(m, "branch")]
    assert len(blocks) == sum(counts)
    assert all(isinstance(b, Bottleneck) == (kind == "bottleneck") for b in blocks)
    # weight layers: stem + 2 or 3 per block + head = the depth in the name
    assert 1 + len(blocks) * (2 if kind == "basic" else 3) + 1 == depth


def test_resnet_output_shape_and_small_images():
    net = ResNetEncoder(5, 12, depth=18, width_mult=0.125)
    assert net(torch.randn(2, 5, 9, 16)).shape == (2, 12)
    assert net(torch.randn(1, 5, 3, 3)).shape == (1, 12)  # 3 x 3 shrinks to 1 x 1
    with pytest.raises(ValueError, match="depth"):
        ResNetEncoder(3, 4, depth=20)


def test_stride_two_stem_halves_the_first_stage_and_keeps_the_weights():
    """The stem's stride changes the feature maps, not the parameters: a stride-1 encoder's weights
    load into the stride-2 one, whose stem output is the stride-1 output at every other cell."""
    torch.manual_seed(0)
    one = ResNetEncoder(5, 12, depth=18, width_mult=0.125)
    two = ResNetEncoder(5, 12, depth=18, width_mult=0.125, stem_stride=2)
    two.load_state_dict(one.state_dict())
    image = torch.randn(2, 5, 32, 32)
    stem_one, stem_two = one.features[0](image), two.features[0](image)
    assert stem_one.shape[-2:] == (32, 32) and stem_two.shape[-2:] == (16, 16)
    torch.testing.assert_close(stem_two, stem_one[..., ::2, ::2])
    assert two.features(image).shape[-2:] == (2, 2) and one.features(image).shape[-2:] == (4, 4)
    with pytest.raises(ValueError, match="stem_stride"):
        ResNetEncoder(3, 4, stem_stride=3)


def test_blocks_are_encoded_independently_and_see_the_mask():
    torch.manual_seed(0)
    enc = RadarBlockEncoder(n_freq=12, n_blocks=3, dim=16, depth=18, width_mult=0.125).eval()
    for p in enc.parameters():  # undo the zero-init of residual branches so every layer matters
        p.data += 0.05 * torch.randn_like(p)
    radar, mask = torch.randn(2, 6, 8, 12), torch.ones(2, 6, 8, dtype=torch.bool)
    base = enc(radar, mask)
    assert base.shape == (2, 3, 16)
    changed = radar.clone()
    changed[..., 4:8] += 1.0  # frequency block 1
    diff = (enc(changed, mask) - base).abs().amax(dim=(0, 2))
    assert diff[0] == 0 and diff[2] == 0 and diff[1] > 0
    mask[:, :3] = False
    assert not torch.allclose(enc(radar, mask), base)


def test_uneven_blocks_are_contiguous_and_padded():
    index = block_frequency_index(10, 4)
    assert index.tolist() == [[0, 1, 2], [3, 4, 5], [6, 7, 10], [8, 9, 10]]  # 10 = the zero channel
    assert block_frequency_index(8, 2).tolist() == [[0, 1, 2, 3], [4, 5, 6, 7]]
    enc = RadarBlockEncoder(n_freq=10, n_blocks=4, dim=8, width_mult=0.125)
    assert enc(torch.randn(2, 3, 4, 10), torch.ones(2, 3, 4, dtype=torch.bool)).shape == (2, 4, 8)
    with pytest.raises(ValueError, match="cannot split"):
        RadarBlockEncoder(n_freq=3, n_blocks=4, dim=8)


def test_roll_conv_wraps_roll_and_zero_pads_aspect():
    from radar2shape.nn.radar_encoder import RollConv2d

    torch.manual_seed(0)
    conv = RollConv2d(2, 3, 3, padding=1, bias=False)
    x = torch.randn(1, 2, 5, 8)
    # by hand: wrap the roll axis (last), zeros along aspect, then a plain valid convolution
    wrapped = torch.cat([x[..., -1:], x, x[..., :1]], dim=-1)
    expected = torch.nn.functional.conv2d(torch.nn.functional.pad(wrapped, (0, 0, 1, 1)), conv.weight)
    assert torch.allclose(conv(x), expected, atol=1e-6)
    # a shift along roll commutes with it (an edge would break this at the seam)
    assert torch.allclose(conv(x.roll(3, dims=-1)), conv(x).roll(3, dims=-1), atol=1e-6)
    plain = torch.nn.Conv2d(2, 3, 3, padding=1, bias=False)
    plain.weight.data.copy_(conv.weight.data)
    assert not torch.allclose(plain(x.roll(3, dims=-1)), plain(x).roll(3, dims=-1), atol=1e-3)


def test_circular_encoder_sees_roll_only_through_its_angle_channels():
    torch.manual_seed(0)
    encoder = RadarBlockEncoder(8, 2, 16, depth=18, width_mult=0.125, roll_padding="circular").eval()
    radar, mask = torch.randn(1, 4, 16, 8), torch.ones(1, 4, 16, dtype=torch.bool)
    turned = radar.roll(8, dims=2)  # 8 roll cells: the ResNet's total stride, so pooling is shift-exact
    assert not torch.allclose(encoder(radar, mask), encoder(turned, mask), atol=1e-4)  # the angle tells the turn
    with torch.no_grad():
        encoder.resnet.features[0].weight[:, -2:] = 0  # blind the angle channels
    assert torch.allclose(encoder(radar, mask), encoder(turned, mask), atol=1e-5)
    assert encoder.resnet.features[0].in_channels == 4 + 1 + 2  # 4 frequencies, mask, cos and sin of roll
