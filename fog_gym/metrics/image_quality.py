"""Image quality against the paired clean frame: PSNR and SSIM on uint8 RGB images, from scikit-image (the
``exp`` extra). SSIM uses scikit-image's defaults for colour images (7 × 7 uniform window, ``channel_axis=-1``,
``data_range=255``).

Example:
    >>> import numpy as np
    >>> a = np.zeros((16, 16, 3), np.uint8)
    >>> psnr(a, a), ssim(a, a)
    (inf, 1.0)
"""

from __future__ import annotations

import numpy as np

from fog_gym.dehaze.classical import check_image


def _pair(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a, b = check_image(a, "a"), check_image(b, "b")
    if a.shape != b.shape:
        raise ValueError(f"a and b must have the same (H, W, 3) shape, got {a.shape} and {b.shape}")
    return a, b


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """Peak signal-to-noise ratio [dB] of two uint8 RGB images (``inf`` when identical)."""
    from skimage.metrics import peak_signal_noise_ratio

    a, b = _pair(a, b)
    if np.array_equal(a, b):
        return float("inf")
    return float(peak_signal_noise_ratio(a, b, data_range=255))


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Structural similarity of two uint8 RGB images (1 when identical); images must be at least 7 × 7."""
    from skimage.metrics import structural_similarity

    a, b = _pair(a, b)
    if min(a.shape[:2]) < 7:
        raise ValueError(f"ssim needs images of at least 7 × 7 pixels, got {a.shape[:2]}")
    return float(structural_similarity(a, b, channel_axis=-1, data_range=255))
