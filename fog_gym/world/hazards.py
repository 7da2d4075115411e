"""Stalled vehicles ahead of the ego (:class:`HazardConfig`): the task where seeing far enough decides the episode
(the ``FogDriveRLHazard-v0`` preset). :func:`place_hazards` puts them on a highway-env road.

Example:
    >>> HazardConfig().first, HazardConfig().gap
    ((60.0, 120.0), (70.0, 140.0))
"""

from __future__ import annotations

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
