"""Stalled vehicles ahead of the ego (:class:`HazardConfig`): the task where seeing far enough decides the episode
(the ``FogDriveRLHazard-v0`` preset). :func:`place_hazards` puts them on a highway-env road.

Example:
    >>> HazardConfig().first, HazardConfig().gap
    ((60.0, 120.0), (70.0, 140.0))
"""

from __future__ import annotations

import math

from dataclasses import dataclass
from typing import Any

import numpy as np

from fog_gym.checks import finite


@dataclass(frozen=True)
class HazardConfig:
    """Stalled vehicles ahead of the ego: a task where seeing far enough decides the episode.

    At every reset, stopped vehicles are placed on the ego's road, the first ``first`` = (min, max) metres ahead of
    the ego, each next one ``gap`` = (min, max) metres further, up to ``span`` metres ahead, each in a lane drawn
    uniformly; traffic within ``clearance`` metres of a stalled vehicle in its lane is removed. Distances and lanes
    come from the reset's seed.

    >>> HazardConfig().first, HazardConfig().gap
    ((60.0, 120.0), (70.0, 140.0))
    >>> HazardConfig(first=(50.0, 40.0))
    Traceback (most recent call last):
    ...
    ValueError: first must be (min, max) metres with 0 < min <= max, got (50.0, 40.0)
    """

    first: tuple[float, float] = (60.0, 120.0)
    gap: tuple[float, float] = (70.0, 140.0)
    span: float = 700.0
    clearance: float = 25.0

    def __post_init__(self) -> None:
        for name in ("first", "gap"):
            v = getattr(self, name)
            ok = isinstance(v, (tuple, list)) and len(v) == 2
            if ok:
                lo, hi = (finite(name, x) for x in v)
                ok = 0 < lo <= hi
            if not ok:
                raise ValueError(f"{name} must be (min, max) metres with 0 < min <= max, got {v!r}")
            object.__setattr__(self, name, (float(v[0]), float(v[1])))
        if not finite("span", self.span) > 0:
            raise ValueError(f"span must be > 0 metres, got {self.span!r}")
        if not finite("clearance", self.clearance) >= 0:
            raise ValueError(f"clearance must be >= 0 metres, got {self.clearance!r}")

    @property
    def capacity(self) -> int:
        """The most stalled vehicles a reset can place: the first at ``first[0]``, then every ``gap[0]`` up to
        ``span`` (the rows of ``info["hazards"]``).

        >>> HazardConfig().capacity
        10
        """
        return int(math.floor((self.span - self.first[0]) / self.gap[0])) + 1 if self.span >= self.first[0] else 0


def hazard_info(rows: np.ndarray, config: HazardConfig) -> dict[str, Any]:
    """``info["hazards"]``: the stalled vehicles' rows (ahead, right, length, width; nearest first at the reset) in a
    fixed ``(config.capacity, 4)`` array, zeros after the last, and ``info["hazard_count"]``: how many rows are real (a
    fixed shape, so Gymnasium's vectorisers stack it).

    >>> info = hazard_info(np.array([[80.0, 4.0, 4.5, 1.8]]), HazardConfig())
    >>> info["hazards"].shape, info["hazard_count"], bool((info["hazards"][1:] == 0).all())
    ((10, 4), 1, True)
    """
    from fog_gym.channels.packing import pad_rows

    return {"hazards": pad_rows(np.asarray(rows, np.float64).reshape(-1, 4), config.capacity),
            "hazard_count": int(len(rows))}


def hazard_rows(info: dict[str, Any]) -> np.ndarray:
    """The real rows of ``info["hazards"]`` (its first ``info["hazard_count"]``): (K, 4) ahead, right, length, width.

    >>> hazard_rows(hazard_info(np.array([[80.0, 4.0, 4.5, 1.8]]), HazardConfig())).tolist()
    [[80.0, 4.0, 4.5, 1.8]]
    """
    return info["hazards"][: info["hazard_count"]]


def place_hazards(road: Any, ego: Any, config: HazardConfig, rng: np.random.Generator) -> list[Any]:
    """Put ``config``'s stalled vehicles (highway-env vehicles at speed 0) on ``road`` ahead of ``ego`` along its
    road edge, removing traffic within ``config.clearance`` of each in its lane; returns them nearest first."""
    from highway_env.vehicle.kinematics import Vehicle

    hz = config
    frm, to, _ = ego.lane_index
    lanes = road.network.graph[frm][to]
    ego_s = float(lanes[ego.lane_index[2]].local_coordinates(ego.position)[0])
    placed: list[Any] = []
    d = float(rng.uniform(*hz.first))
    while d <= hz.span:
        lane = lanes[int(rng.integers(len(lanes)))]
        s = ego_s + d
        if s > lane.length:
            break
        for v in list(road.vehicles):
            lon, lat = lane.local_coordinates(v.position)
            if v is not ego and v not in placed and abs(lon - s) < hz.clearance and abs(lat) < lane.width_at(s):
                road.vehicles.remove(v)
        v = Vehicle(road, lane.position(s, 0.0), lane.heading_at(s), 0.0)
        road.vehicles.append(v)
        placed.append(v)
        d += float(rng.uniform(*hz.gap))
    return placed
