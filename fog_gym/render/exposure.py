"""Auto-exposure of the night cameras: a log-luminance histogram per camera and the gain that puts the mean of its
middle percentiles at the key value (:mod:`fog_gym.render.lights` runs it on a small render of each night frame).

Example:
    >>> lin = np.full((1, 4, 4, 3), 0.05, np.float32)
    >>> g = exposure_gains(lin)[0]
    >>> bool(abs(g * 0.05 - KEY) / KEY < 0.1)
    True
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

import fog_gym._numba  # noqa: F401  (numba's fork-safe threading layer, before any kernel runs)
from fog_gym._numba import launch

#: Histogram span (log2 luminance) and bins; the percentile window the mean is taken over; the key value; the gain's
#: limits.
LOG_MIN, LOG_MAX, N_BINS = -12.0, 4.0, 128
LOW_PERCENT, HIGH_PERCENT = 0.5, 0.98
KEY = 0.18
GAIN_MIN, GAIN_MAX = 1.0, 16.0


@njit(cache=True, nogil=True, parallel=True)
def _log_histograms(lin, log_min, log_max, n_bins):
    n_cam, height, width, _ = lin.shape
    hist = np.zeros((n_cam, height, n_bins), np.int64)
    scale = n_bins / (log_max - log_min)
    for task in prange(n_cam * height):
        c = task // height
        i = task % height
        for j in range(width):
            y = 0.2126 * lin[c, i, j, 0] + 0.7152 * lin[c, i, j, 1] + 0.0722 * lin[c, i, j, 2]
            b = 0
            if y > 0.0:
                b = int((math.log2(y) - log_min) * scale)
                b = min(max(b, 0), n_bins - 1)
            hist[c, i, b] += 1
    return hist.sum(axis=1)


def exposure_gains(lin: np.ndarray) -> np.ndarray:
    """Auto-exposure gain per camera from linear radiance ``lin`` (C, H, W, 3); see the module docstring.

    >>> lin = np.full((1, 4, 4, 3), 0.05, np.float32)
    >>> g = exposure_gains(lin)[0]
    >>> bool(abs(g * 0.05 - KEY) / KEY < 0.1)
    True
    """
    hist = launch(_log_histograms)(np.ascontiguousarray(lin, np.float32), LOG_MIN, LOG_MAX, N_BINS)
    return gains_from_histograms(hist)


def gains_from_histograms(hist: np.ndarray) -> np.ndarray:
    """Exposure gain per camera from (C, N_BINS) log-luminance histograms."""
    centres = LOG_MIN + (np.arange(N_BINS) + 0.5) * (LOG_MAX - LOG_MIN) / N_BINS
    gains = np.empty(len(hist))
    for c, h in enumerate(hist):
        cum = np.cumsum(h) / max(h.sum(), 1)
        lo = np.r_[0.0, cum[:-1]]
        # the fraction of each bin that lies inside [LOW_PERCENT, HIGH_PERCENT]
        w = np.clip(np.minimum(cum, HIGH_PERCENT) - np.maximum(lo, LOW_PERCENT), 0.0, None)
        mean_log = float((w * centres).sum() / max(w.sum(), 1e-12))
        gains[c] = float(np.clip(KEY / 2.0**mean_log, GAIN_MIN, GAIN_MAX))
    return gains
