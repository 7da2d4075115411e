"""Keep freed frame buffers for reuse (glibc only; set FOG_GYM_MALLOC_TUNING=0 to leave malloc alone).

Every step allocates tens of megabytes of fresh images (cameras, fog levels). glibc hands allocations above its
mmap threshold (128 kB, rising to at most 32 MB) straight from the kernel and returns them on free, so each new
frame pays page faults that cost more than rendering it (measured: 4 × 11 MB of fog output, 16 ms of work, 39 ms
with faults). Raising the mmap threshold to its 32 MB ceiling and the trim threshold to 1 GB makes freed frames
stay in the heap and be reused, at the price of the process keeping its peak heap.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3


def tune_malloc() -> bool:
    """Apply the tuning once per process; True if it was applied."""
    if os.environ.get("FOG_GYM_MALLOC_TUNING", "1") == "0" or not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    ok = mallopt(_M_MMAP_THRESHOLD, 32 * 1024 * 1024) == 1
    ok &= mallopt(_M_TRIM_THRESHOLD, 1024 * 1024 * 1024) == 1
    return bool(ok)
