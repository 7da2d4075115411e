"""Small numba helpers on 2D polygons (pure; used by the box labels and the 3D detection metrics).

Example:
    >>> import numpy as np
    >>> polygon_area(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]), 4)
    2.0
"""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def polygon_area(poly, n):
    """Area of the first ``n`` vertices of ``poly`` (shoelace; either orientation)."""
    s = 0.0
    for k in range(n):
        k1 = (k + 1) % n
        s += poly[k, 0] * poly[k1, 1] - poly[k1, 0] * poly[k, 1]
    return abs(s) / 2.0
