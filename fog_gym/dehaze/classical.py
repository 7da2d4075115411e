"""Classical dehazers on uint8 ``(H, W, 3)`` RGB images: He et al.'s Dark Channel Prior and an oracle that
inverts fog-gym's Koschmieder fog exactly (the upper bound of any dehazer). The learned ones live beside it
(:mod:`fog_gym.dehaze.aodnet`, :mod:`fog_gym.dehaze.dehazeformer`). Pure numpy + OpenCV (box filters and erosion, both O(1) per pixel in the window).

Dark Channel Prior (He, Sun, Tang, CVPR 2009 / TPAMI 2011), as specified:

* dark channel ``D(x) = min_{y ∈ Ω(x)} min_c I_c(y)`` over a ``patch`` × ``patch`` window (15);
* airlight ``A``: among the brightest ``top`` (0.1 %) pixels of D, the input pixel of highest intensity (sum of RGB);
* transmission ``t̃ = 1 − ω · dark(I / A)`` with ω = 0.95, refined by a guided filter (He et al., ECCV 2010) with
  the grey input as guide (radius ``radius``, regulariser ``eps``; the guided filter replaces the original
  soft matting, as the authors recommend);
* ``J = (I − A) / max(t, t0) + A`` with t0 = 0.1, clipped to [0, 255].

Example:
    >>> img = np.full((32, 32, 3), 120, np.uint8)
    >>> dcp(img).shape, dcp(img).dtype
    ((32, 32, 3), dtype('uint8'))
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np


def check_image(image: np.ndarray, name: str = "image") -> np.ndarray:
    """A uint8 ``(H, W, 3)`` RGB image, or ``ValueError`` naming the expected shape and dtype."""
    img = np.asarray(image)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"{name} must be a uint8 (H, W, 3) RGB array, got {img.dtype} {img.shape}")
    return img


def guided_filter(guide: np.ndarray, src: np.ndarray, radius: int, eps: float, subsample: int = 1) -> np.ndarray:
    """He et al.'s guided filter of ``src`` with a single-channel ``guide`` (both float32 in [0, 1]); with
    ``subsample`` s > 1 the linear coefficients are fitted on an s× smaller grid and upsampled (He & Sun's fast
    guided filter, 2015), which changes the result little for the smooth transmission maps it is used on."""
    h, w = guide.shape
    if subsample > 1:
        size = (max(1, w // subsample), max(1, h // subsample))
        g, p = (cv2.resize(x, size, interpolation=cv2.INTER_AREA) for x in (guide, src))
        radius = max(1, round(radius / subsample))
    else:
        g, p = guide, src
    k = (2 * radius + 1, 2 * radius + 1)

    def box(x: np.ndarray) -> np.ndarray:
        return cv2.boxFilter(x, cv2.CV_32F, k, borderType=cv2.BORDER_REFLECT)

    mean_i, mean_p = box(g), box(p)
    a = (box(g * p) - mean_i * mean_p) / (box(g * g) - mean_i * mean_i + eps)
    b = mean_p - a * mean_i
    mean_a, mean_b = box(a), box(b)
    if subsample > 1:
        mean_a, mean_b = (cv2.resize(x, (w, h), interpolation=cv2.INTER_LINEAR) for x in (mean_a, mean_b))
    return mean_a * guide + mean_b


def estimate_airlight(image: np.ndarray, dark: np.ndarray, top: float = 0.001) -> np.ndarray:
    """``(3,)`` airlight: the brightest input pixel (highest R + G + B, first in raster order on a tie) among the
    top ``top`` fraction of the uint8 dark channel ``dark``, every pixel tied with the last one included (so the
    choice never depends on a sort's tie order). A histogram finds the threshold: O(pixels), no sort.

    >>> img = np.zeros((10, 10, 3), np.uint8); img[2, 3] = (200, 210, 220); img[5, 5] = (250, 250, 250)
    >>> dark = np.zeros((10, 10), np.uint8); dark[2, 3] = 9; dark[5, 5] = 1
    >>> estimate_airlight(img, dark, top=0.01).tolist()
    [200.0, 210.0, 220.0]
    """
    d = np.ascontiguousarray(dark)
    if d.dtype != np.uint8 or d.shape != image.shape[:2]:
        raise ValueError(f"dark must be the image's uint8 (H, W) dark channel, got {d.dtype} {d.shape}")
    n = max(1, int(round(d.size * top)))
    hist = cv2.calcHist([d], [0], None, [256], [0, 256]).reshape(-1)
    at_least = np.cumsum(hist[::-1])[::-1]  # pixels with dark >= v, for each v
    threshold = int(np.flatnonzero(at_least >= n)[-1])
    r, g, b = cv2.split(np.ascontiguousarray(image))
    brightness = cv2.add(cv2.add(r, g, dtype=cv2.CV_16U), b, dtype=cv2.CV_16U)
    _, _, _, (x, y) = cv2.minMaxLoc(brightness, mask=(d >= threshold).view(np.uint8))
    return image[y, x].astype(np.float64)


def dcp(image: np.ndarray, patch: int = 15, omega: float = 0.95, t0: float = 0.1, top: float = 0.001,
        radius: int = 40, eps: float = 1e-3, airlight: Sequence[float] | None = None,
        subsample: int = 4) -> np.ndarray:  # fmt: skip
    """Dark Channel Prior dehazing (module docstring); ``airlight`` overrides the estimate; ``subsample`` is the
    fast guided filter's factor (1: the exact filter)."""
    img = check_image(image)
    if patch < 1 or patch % 2 == 0:
        raise ValueError(f"patch must be a positive odd integer, got {patch}")
    if not (0 < omega <= 1 and 0 < t0 < 1):
        raise ValueError(f"need 0 < omega <= 1 and 0 < t0 < 1, got {omega} and {t0}")
    # every full-resolution step is an OpenCV call on single channels (SIMD, threaded): ≈ 2.5× the numpy version
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (patch, patch))
    chans = cv2.split(np.ascontiguousarray(img))
    dark = cv2.erode(cv2.min(cv2.min(chans[0], chans[1]), chans[2]), kernel, borderType=cv2.BORDER_REPLICATE)
    A = np.asarray(airlight, np.float64) if airlight is not None else estimate_airlight(img, dark, top)
    A = np.maximum(A, 1.0)
    norm = [cv2.multiply(c, float(1.0 / a), dtype=cv2.CV_32F) for c, a in zip(chans, A, strict=True)]
    t = 1.0 - omega * cv2.erode(cv2.min(cv2.min(norm[0], norm[1]), norm[2]), kernel, borderType=cv2.BORDER_REPLICATE)
    grey = cv2.multiply(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY), 1.0 / 255.0, dtype=cv2.CV_32F)
    t = guided_filter(grey, t, radius, eps, subsample if min(img.shape[:2]) >= 8 * subsample else 1)
    inv_t = 1.0 / cv2.max(t, t0)
    # J = (I − A) / max(t, t0) + A, rounded and saturated to 0–255 by OpenCV's conversion
    out = [cv2.add(cv2.multiply(cv2.subtract(c, float(a), dtype=cv2.CV_32F), inv_t), float(a), dtype=cv2.CV_8U)
           for c, a in zip(chans, A, strict=True)]  # fmt: skip
    return cv2.merge(out)


def oracle(fogged: np.ndarray, depth: np.ndarray, K: np.ndarray, alpha: float, airlight: Sequence[float],
           t_min: float = 0.05) -> np.ndarray:  # fmt: skip
    """Invert fog-gym's Koschmieder fog exactly: ``J = (I − A·(1 − t)) / t``, ``t = exp(−α·ℓ)`` with the Euclidean
    ray length ℓ from planar ``depth`` and ``K`` — the same transmission the fog was made with. Only the 8-bit
    rounding of I is lost (amplified by 1/t, so far pixels in dense fog come back noisier). Where ``t < t_min``
    (the sky, far road in dense fog) the fog has left almost nothing of J — at ``t = 0.05`` the rounding alone is
    ±10 grey levels, and the sky's ``t`` is ~0 — so those pixels keep their fogged value."""
    from fog_gym.fog import ray_length_factor

    img = check_image(fogged, "fogged")
    d = np.asarray(depth, np.float32)
    if d.shape != img.shape[:2] or not np.isfinite(d).all() or (d < 0).any():
        raise ValueError(f"depth must be a finite non-negative (H, W) array matching the image, got {d.shape}")
    if not (np.isfinite(alpha) and alpha >= 0):
        raise ValueError(f"alpha must be a finite number >= 0, got {alpha!r}")
    h, w = d.shape
    t = np.exp(-np.float32(alpha) * d * ray_length_factor(w, h, np.asarray(K, np.float64)))[..., None]
    A = np.asarray(airlight, np.float32).reshape(1, 1, 3)
    if not 0 < t_min < 1:
        raise ValueError(f"t_min must lie in (0, 1), got {t_min!r}")
    out = (img.astype(np.float32) - A * (1.0 - t)) / np.maximum(t, t_min)
    out = np.where(t >= t_min, out, img.astype(np.float32))
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)
