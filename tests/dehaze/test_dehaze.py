"""Dehazers and image quality: DCP undoes synthetic fog where its prior holds, the oracle inverts fog-gym's fog
to within rounding, PSNR/SSIM identities, bad input."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.dehaze import dcp, estimate_airlight, guided_filter, oracle
from fog_gym.fog import alpha_from_visibility, fog_image, ray_length_factor
from fog_gym.geometry import intrinsic_matrix
from fog_gym.metrics.image_quality import psnr, ssim

pytest.importorskip("skimage")  # in the dev extra: never skipped in CI


def _scene(h=120, w=160, seed=0):
    """A clean image with a dark pixel in every 15 × 15 patch (DCP's prior), and a depth ramp 5–40 m."""
    rng = np.random.default_rng(seed)
    clean = rng.integers(60, 230, (h, w, 3), dtype=np.uint8)
    clean[::7, ::7] = rng.integers(0, 8, clean[::7, ::7].shape, dtype=np.uint8)
    depth = np.repeat(np.linspace(40.0, 5.0, h, dtype=np.float32)[:, None], w, axis=1)
    return clean, depth, intrinsic_matrix(w, h, 100.0)


def test_dcp_undoes_fog_where_the_dark_channel_prior_holds():
    clean, depth, K = _scene()
    A = np.array([210.0, 210.0, 215.0])
    foggy = fog_image(clean, depth, K, alpha_from_visibility(100.0), A)
    restored = dcp(foggy, subsample=1)
    assert psnr(restored, clean) > psnr(foggy, clean) + 5.0
    assert ssim(restored, clean) > ssim(foggy, clean)


def test_the_oracle_inverts_koschmieder_to_within_rounding():
    clean, depth, K = _scene(seed=1)
    A = np.array([200.0, 205.0, 210.0])
    alpha = alpha_from_visibility(50.0)
    foggy = fog_image(clean, depth, K, alpha, A)
    back = oracle(foggy, depth, K, alpha, A)
    t = np.exp(-alpha * depth * ray_length_factor(160, 120, K))[..., None]
    err = np.abs(back.astype(float) - clean.astype(float))
    tt = np.broadcast_to(t, err.shape)
    kept = tt >= 0.05  # the default t_min
    assert kept.mean() > 0.5
    assert (err[kept] <= 0.5 / tt[kept] + 1.0).all()  # I was rounded to 1/2 grey level; J's error grows as 1/t
    assert np.array_equal(back[~kept], foggy[~kept])  # below t_min the fog left nothing to recover: kept as fogged
    fog_err = np.abs(foggy.astype(float) - clean.astype(float))
    assert np.mean(err[tt > 0.2]) < 1.0 and np.mean(err[kept]) < 0.1 * np.mean(fog_err[kept])
    assert psnr(back, clean) > psnr(foggy, clean) + 5.0
    assert np.array_equal(oracle(clean, depth, K, 0.0, A), clean)  # no fog: nothing to undo


def test_the_fast_guided_filter_stays_close_to_the_exact_one():
    rng = np.random.default_rng(2)
    guide = rng.random((240, 320)).astype(np.float32)
    src = np.clip(np.linspace(0, 1, 320, dtype=np.float32)[None, :] + 0.05 * rng.standard_normal((240, 320)), 0, 1)
    exact, fast = guided_filter(guide, src.astype(np.float32), 20, 1e-3), guided_filter(guide, src.astype(np.float32), 20, 1e-3, 4)
    assert np.abs(exact - fast).mean() < 0.02


def test_identical_images_have_infinite_psnr_and_ssim_one():
    img = np.random.default_rng(3).integers(0, 256, (32, 32, 3), dtype=np.uint8)
    assert psnr(img, img) == float("inf") and ssim(img, img) == pytest.approx(1.0)
    worse = img.copy()
    worse[0, 0] ^= 1
    assert 40.0 < psnr(img, worse) < float("inf") and ssim(img, worse) < 1.0


@pytest.mark.parametrize("call, message", [
    (lambda: dcp(np.zeros((8, 8), np.uint8)), r"image must be a uint8 \(H, W, 3\) RGB array, got uint8 \(8, 8\)"),
    (lambda: dcp(np.zeros((8, 8, 3), np.float32)), "got float32"),
    (lambda: dcp(np.zeros((8, 8, 4), np.uint8)), r"\(8, 8, 4\)"),
    (lambda: dcp(np.zeros((8, 8, 3), np.uint8), patch=4), "patch must be a positive odd integer"),
    (lambda: psnr(np.zeros((8, 8, 3), np.uint8), np.zeros((8, 9, 3), np.uint8)), "same"),
    (lambda: ssim(np.zeros((5, 5, 3), np.uint8), np.zeros((5, 5, 3), np.uint8)), "at least 7"),
    (lambda: oracle(np.zeros((4, 4, 3), np.uint8), np.zeros((3, 4)), np.eye(3), 0.1, [1, 1, 1]), "depth must be"),
])  # fmt: skip
def test_bad_input_names_the_expected_shape(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_aodnet_has_the_papers_size_and_learns_to_undo_fog():
    torch = pytest.importorskip("torch")
    from fog_gym.dehaze.aodnet import AODNet, dehaze, train_aodnet

    assert sum(p.numel() for p in AODNet().parameters()) == 1761
    clean, depth, K = _scene(48, 64, seed=4)
    crops = np.stack([np.roll(clean, (7 * k, 5 * k), axis=(0, 1)) for k in range(16)])
    A = np.array([205.0, 205.0, 210.0])
    foggy = np.stack([fog_image(c, depth, K, alpha_from_visibility(100.0), A) for c in crops])
    torch.manual_seed(0)
    model, losses = train_aodnet(crops, foggy, epochs=30, batch_size=8, lr=3e-3, progress=False)
    assert losses[-1] < 0.5 * losses[0]
    assert psnr(dehaze(model, foggy[0]), crops[0]) > psnr(foggy[0], crops[0])
    with pytest.raises(ValueError, match="uint8 \\(N, H, W, 3\\) arrays of one shape"):
        train_aodnet(crops, foggy[:3])


@settings(max_examples=60, deadline=None)
@given(h=st.integers(1, 40), w=st.integers(1, 40), top=st.sampled_from([0.001, 0.01, 0.1, 0.5, 1.0]),
       levels=st.integers(1, 256), seed=st.integers(0, 2**31 - 1))  # fmt: skip
def test_airlight_is_the_brightest_pixel_among_the_top_of_the_dark_channel_ties_included(h, w, top, levels, seed):
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    dark = rng.integers(0, levels, (h, w), dtype=np.uint8)  # few levels: many ties at the threshold
    n = max(1, int(round(dark.size * top)))
    threshold = np.sort(dark.ravel())[::-1][n - 1]
    candidates = np.flatnonzero(dark.ravel() >= threshold)
    brightest = candidates[np.argmax(img.reshape(-1, 3)[candidates].astype(int).sum(1))]  # first on a tie
    assert estimate_airlight(img, dark, top).tolist() == img.reshape(-1, 3)[brightest].astype(float).tolist()
