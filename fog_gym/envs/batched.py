"""The perceived-objects worlds' per-step results as arrays over all worlds, with no Python per world (numba kernels).

What :class:`~fog_gym.envs.objects.ObjectWorlds` gives one world at a time — its reward, termination, hazards and
detections — computed for every world in one pass, and :func:`batched_infos`, which assembles the infos that
Gymnasium's ``VectorEnv._add_info`` would build from the worlds' single infos (the same keys, ``_key`` masks, dtypes
and values; rows of worlds outside the mask zero, as ``_add_info`` leaves them) straight from those arrays. The
native vector env's differential test against ``SyncVectorEnv`` holds them to it.

Example:
    >>> mask = np.array([True, False, True])
    >>> out = {}
    >>> put(out, "step", np.array([4, 9, 2]), mask, np.int64)
    >>> out["step"].tolist(), out["_step"].tolist()
    ([4, 0, 2], [True, False, True])
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import VectorEnv
from numba import njit

from fog_gym.world.traffic import kernels as K

#: highway-env's reward terms in the order ``NativeTraffic.rewards`` lists them (their weights come from the config).
REWARD_TERMS = ("collision_reward", "right_lane_reward", "high_speed_reward", "on_road_reward")


def put(out: dict[str, Any], key: str, values: np.ndarray, mask: np.ndarray, dtype: Any) -> None:
    """``out[key]`` = ``values`` in the rows of ``mask`` (zeros elsewhere), ``out["_" + key]`` = the mask."""
    arr = np.zeros(values.shape, dtype)
    arr[mask] = values[mask]
    out[key], out[f"_{key}"] = arr, mask.copy()


@njit(cache=True, nogil=True)
def batch_rewards(floats, ints, lanes, speed_lo, speed_hi, weights, normalize, norm_lo, norm_hi, active, out):
    """``NativeTraffic.reward`` of every active world: the weighted terms (summed in the config's order), normalised
    as highway-env does, times the on-road term."""
    terms = np.zeros(6)
    for w in range(floats.shape[0]):
        if not active[w]:
            continue
        terms[:] = 0.0
        terms[0], terms[1] = speed_lo, speed_hi
        K.highway_rewards(floats[w], ints[w], lanes, terms)
        r = weights[0] * terms[2] + weights[1] * terms[3] + weights[2] * terms[4] + weights[3] * terms[5]
        if normalize:
            r = 0 + (r - norm_lo) * (1 - 0) / (norm_hi - norm_lo)
        out[w] = r * terms[5]
    return out


@njit(cache=True, nogil=True)
def batch_hazards(floats, slots, out):
    """``NativeTraffic.hazards_ego`` of every world in a fixed ``(capacity, 4)`` array (``slots``: each world's
    stalled vehicles, −1 after the last); returns the counts."""
    n_w, cap = slots.shape
    counts = np.zeros(n_w, np.int64)
    out[:] = 0.0
    for w in range(n_w):
        ex, ey, eh = floats[w, 0, K.FX], floats[w, 0, K.FY], floats[w, 0, K.FH]
        c, s = np.cos(eh), np.sin(eh)
        k = 0
        for q in range(cap):
            v = slots[w, q]
            if v < 0:
                break
            dx, dy = floats[w, v, K.FX] - ex, floats[w, v, K.FY] - ey
            out[w, k, 0] = dx * c + dy * s
            out[w, k, 1] = -dx * s + dy * c
            out[w, k, 2] = floats[w, v, K.FLEN]
            out[w, k, 3] = floats[w, v, K.FWID]
            k += 1
        counts[w] = k
    return counts


@njit(cache=True, nogil=True)
def batch_detections(floats, counts, ids, present, pos, sensor, out_count, out_ids, out_pos, out_true, out_dist):
    """``ObjectWorlds.detections`` of one sensor slot (``sensor``) for every world: the detected vehicles' ids,
    reported positions, true positions (ego frame) and true distances, packed first, fills after (ids −1, zeros)."""
    n_w, cap = ids.shape
    out_ids[:] = -1
    out_pos[:] = 0.0
    out_true[:] = 0.0
    out_dist[:] = 0.0
    for w in range(n_w):
        ex, ey, eh = floats[w, 0, K.FX], floats[w, 0, K.FY], floats[w, 0, K.FH]
        cs, sn = np.cos(eh), np.sin(eh)
        k = 0
        for v in range(counts[w]):
            if not present[w, v, sensor]:
                continue
            dx, dy = floats[w, v, K.FX] - ex, floats[w, v, K.FY] - ey
            tx, ty = dx * cs + dy * sn, -dx * sn + dy * cs
            out_ids[w, k] = ids[w, v]
            out_pos[w, k, 0] = pos[w, v, sensor, 0]
            out_pos[w, k, 1] = pos[w, v, sensor, 1]
            out_true[w, k, 0] = tx
            out_true[w, k, 1] = ty
            out_dist[w, k] = np.hypot(tx, ty)
            k += 1
        out_count[w] = k


class _Batch:
    """What Gymnasium's ``VectorEnv._add_info`` needs of a vector env: its width (and itself, to recurse)."""

    _add_info = VectorEnv._add_info

    def __init__(self, num_envs: int) -> None:
        self.num_envs = num_envs


def add_infos(infos: dict[str, Any], per_world: dict[int, dict[str, Any]], num_envs: int) -> dict[str, Any]:
    """Gymnasium's own ``VectorEnv._add_info`` of each world's info dict, in world order (for the parts that are
    not arrays: a world's fog description)."""
    batch = _Batch(num_envs)
    for i in sorted(per_world):
        infos = batch._add_info(infos, per_world[i], i)
    return infos


def copy_infos(infos: dict[str, Any]) -> dict[str, Any]:
    """A copy of an infos dict whose arrays the caller may change (a cached part is handed out again next step)."""
    return {k: copy_infos(v) if isinstance(v, dict) else v.copy() if isinstance(v, np.ndarray) else v
            for k, v in infos.items()}  # fmt: skip
