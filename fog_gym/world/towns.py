"""Towns: the six highway-env scenarios fog-gym drives (FogDrive's ``T<n>`` numbering is their order), the
fog-gym config each gets on top of highway-env's defaults, its scenery style and its IDM profile; times of day and
the traffic-core modes.

Example:
    >>> TOWNS[0], TOWN_SPECS["roundabout"].scenery
    ('highway', 'urban')
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

#: Towns in FogDrive order; a town's FogDrive number ``T<n>`` is its 1-based position.
TOWNS: tuple[str, ...] = ("highway", "merge", "roundabout", "intersection", "racetrack", "exit")
TIMES_OF_DAY: tuple[str, ...] = ("day", "night")
#: Allowed values of the ``traffic=`` argument of FogDrive environments.
TRAFFIC_MODES: tuple[str, ...] = ("fast", "reference", "native")


def check_traffic_mode(traffic: str) -> str:
    """Validate a ``traffic=`` value.

    >>> check_traffic_mode("fast")
    'fast'
    >>> check_traffic_mode("numba")
    Traceback (most recent call last):
    ...
    ValueError: traffic must be one of ('fast', 'reference', 'native'), got 'numba'
    """
    if not isinstance(traffic, str) or traffic not in TRAFFIC_MODES:
        raise ValueError(f"traffic must be one of {TRAFFIC_MODES}, got {traffic!r}")
    return traffic


#: highway-env's IDM class constants, which IntersectionEnv overwrites process-wide (research note): each town
#: names its profile in its :class:`TownSpec`, and a world re-applies it before it steps, so towns in one process
#: do not leak.
IDM_PROFILES: dict[str, dict[str, float]] = {
    "default": {"DISTANCE_WANTED": 10.0, "COMFORT_ACC_MAX": 3.0, "COMFORT_ACC_MIN": -5.0},
    "intersection": {"DISTANCE_WANTED": 7.0, "COMFORT_ACC_MAX": 6.0, "COMFORT_ACC_MIN": -3.0},
}


@dataclass(frozen=True)
class TownSpec:
    """A town: the highway-env scenario class, fog-gym's config on top of its defaults, a scenery style and the
    IDM profile (a key of :data:`IDM_PROFILES`)."""

    env_class: str
    config: dict[str, Any]
    scenery: str
    idm: str = "default"

    def __post_init__(self) -> None:
        if self.idm not in IDM_PROFILES:
            raise ValueError(f"idm must be one of {tuple(IDM_PROFILES)}, got {self.idm!r}")


TOWN_SPECS: dict[str, TownSpec] = {
    "highway": TownSpec("HighwayEnv", {"lanes_count": 4, "vehicles_count": 40, "vehicles_density": 1.2}, "freeway"),
    "merge": TownSpec("MergeEnv", {}, "freeway"),
    "roundabout": TownSpec("RoundaboutEnv", {}, "urban"),
    "intersection": TownSpec("IntersectionEnv", {"initial_vehicle_count": 12}, "urban", idm="intersection"),
    "racetrack": TownSpec("RacetrackEnv", {"other_vehicles": 8}, "circuit"),
    "exit": TownSpec("ExitEnv", {"vehicles_count": 30}, "freeway"),
}
assert tuple(TOWN_SPECS) == TOWNS


def highway_env_config(town: str, simulation_frequency: int = 20, keyframe_frequency: int = 10,
                       overrides: dict[str, Any] | None = None) -> dict[str, Any]:  # fmt: skip
    """The highway-env config of a town's scenario as :class:`TrafficWorld` builds it (benchmarks use it to build the
    bare scenario for comparison).

    >>> highway_env_config("highway")["vehicles_count"], highway_env_config("merge", overrides={"lanes_count": 3})["lanes_count"]
    (40, 3)
    """
    if town not in TOWN_SPECS:
        raise ValueError(f"town must be one of {TOWNS}, got {town!r}")
    config = copy.deepcopy(TOWN_SPECS[town].config)
    config.update(
        {
            "simulation_frequency": simulation_frequency,
            "policy_frequency": keyframe_frequency,
            "duration": 1e9,  # fog-gym truncates by its own episode length
            "offscreen_rendering": True,
        }
    )
    config.update(copy.deepcopy(dict(overrides or {})))
    return config


def apply_idm_profile(town: str) -> None:
    """Set highway-env's process-wide IDM constants to ``town``'s profile (its :class:`TownSpec` names it)."""
    from highway_env.vehicle.behavior import IDMVehicle

    for k, v in IDM_PROFILES[TOWN_SPECS[town].idm].items():
        setattr(IDMVehicle, k, v)
