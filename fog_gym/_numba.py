"""Numba set-up shared by every module with parallel kernels; import it before defining a kernel.

GNU OpenMP, numba's usual pick, aborts a process that forks after a parallel kernel ran; Gymnasium's
AsyncVectorEnv and SB3's SubprocVecEnv fork. The workqueue layer is fork-safe (but not for concurrent kernel
launches from several Python threads). ``NUMBA_THREADING_LAYER`` still overrides.
"""

from __future__ import annotations

import os

import numba

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"
