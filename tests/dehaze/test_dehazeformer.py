"""DehazeFormer: shapes, parameter count at the T size, the residual form J = K·I − B + I, RescaleNorm, training."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")  # the torch extra is part of the dev extra: never skipped in CI

from fog_gym.dehaze.dehazeformer import DehazeFormer, RescaleNorm, dehaze, train_dehazeformer  # noqa: E402


@pytest.mark.parametrize("h, w", [(32, 32), (30, 45), (64, 24)])
def test_any_image_size_comes_back_at_its_size(h, w):
    net = DehazeFormer("T").eval()
    with torch.no_grad():
        out = net(torch.rand(2, 3, h, w))
    assert out.shape == (2, 3, h, w) and float(out.min()) >= 0.0 and float(out.max()) <= 1.0


def test_sizes_and_their_parameter_counts():
    count = lambda m: sum(p.numel() for p in m.parameters())  # noqa: E731
    t, s = count(DehazeFormer("T")), count(DehazeFormer("S"))
    assert 0.6e6 < t < 0.8e6 and 1.1e6 < s < 1.5e6  # the published ≈ 0.69 M and ≈ 1.28 M
    with pytest.raises(ValueError, match="size must be one of"):
        DehazeFormer("XL")


def test_the_output_is_the_residual_form_of_the_last_layer():
    """With the last convolution made to output K = 0 and B = 0, the network returns its input (J = K·I − B + I);
    with K = 0 and B = b, the input shifted by −b in [−1, 1] units."""
    net = DehazeFormer("T").eval()
    torch.nn.init.zeros_(net.out.weight)
    torch.nn.init.zeros_(net.out.bias)
    x = torch.rand(1, 3, 16, 24) * 0.8 + 0.1
    with torch.no_grad():
        assert torch.allclose(net(x), x, atol=1e-6)
        net.out.bias[1:] = 0.2  # B = 0.2 in [−1, 1] units = 0.1 in [0, 1] units
        assert torch.allclose(net(x), x - 0.1, atol=1e-6)
        net.out.bias[:] = torch.tensor([1.0, 0.0, 0.0, 0.0])  # K = 1: J = 2 I (in [−1, 1])
        i = x * 2 - 1
        assert torch.allclose(net(x), ((2 * i + 1) / 2).clamp(0, 1), atol=1e-6)


def test_rescale_norm_normalises_each_sample_and_returns_its_statistics():
    norm = RescaleNorm(4)
    x = torch.randn(3, 4, 5, 6) * torch.tensor([1.0, 5.0, 0.1])[:, None, None, None] + 2.0
    y, scale, shift = norm(x)
    assert torch.allclose(y.mean(dim=(1, 2, 3)), torch.zeros(3), atol=1e-5)
    assert torch.allclose(y.pow(2).mean(dim=(1, 2, 3)), torch.ones(3), atol=5e-3)  # (σ² / (σ² + ε))
    # at initialisation the rescale is σ + 1 and the rebias is 0 · μ + 0... through 1 × 1 convolutions of σ and μ
    sd = x.std(dim=(1, 2, 3), unbiased=False)
    w1, b1 = norm.meta1.weight.view(-1), norm.meta1.bias
    assert torch.allclose(scale[:, :, 0, 0], sd[:, None] * w1 + b1, atol=1e-4)
    assert shift.shape == (3, 4, 1, 1)


def test_training_lowers_the_l1_loss_on_fogged_pairs_and_dehaze_returns_uint8():
    rng = np.random.default_rng(0)
    clean = rng.integers(0, 255, (6, 32, 32, 3), dtype=np.uint8)
    foggy = (0.6 * clean + 0.4 * 200).astype(np.uint8)  # a uniform haze
    model, losses = train_dehazeformer(clean, foggy, "T", steps=100, batch_size=2, crop=16, lr=2e-3, seed=0,
                                       progress=False)  # fmt: skip
    assert len(losses) == 2 and losses[-1] < 0.7 * losses[0]  # means of steps 0-49 and 50-99
    out = dehaze(model, foggy[0])
    assert out.shape == (32, 32, 3) and out.dtype == np.uint8
    with pytest.raises(ValueError, match="crop"):
        train_dehazeformer(clean, foggy, steps=1, crop=64, progress=False)
