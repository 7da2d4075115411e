"""The environment's configuration: :class:`FogDriveConfig`, everything that defines a FogDrive-v0 environment
apart from the seed (town, time of day, rig, timing, labels, traffic core, hazards). It validates itself and
raises :class:`ValueError` naming the argument and the allowed values, so bad input fails before any work starts.

Example:
    >>> FogDriveConfig(town="roundabout", time_of_day="night").episode_steps
    200
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from fog_gym.checks import finite
from fog_gym.labels.boxes import LabelConfig
from fog_gym.sensors.rig import RigConfig
from fog_gym.world.hazards import HazardConfig
from fog_gym.world.towns import TIMES_OF_DAY, TOWNS, check_traffic_mode

#: Allowed values of ``FogDriveConfig.geometry``: what the sensors see of a vehicle — ``"boxes"`` (a body and a
#: cabin box, wheels and lamps) or ``"meshes"`` (a procedural body type, :mod:`fog_gym.world.bodies`).
GEOMETRIES: tuple[str, ...] = ("boxes", "meshes")
#: Allowed values of ``FogDriveConfig.static_world``.
STATIC_WORLDS: tuple[str, ...] = ("episode", "town")


@dataclass(frozen=True)
class FogDriveConfig:
    """Everything that defines a FogDrive-v0 environment apart from the seed.

    ``highway_config`` is passed to the highway-env scenario on top of fog-gym's settings (for example
    ``{"vehicles_count": 30}`` or ``{"action": {"type": "ContinuousAction"}}``).

    >>> FogDriveConfig(town="roundabout", time_of_day="night").episode_steps
    200
    """

    town: str = "highway"
    time_of_day: str = "day"
    rig: RigConfig = field(default_factory=RigConfig.fogdrive)
    simulation_frequency: int = 20
    keyframe_frequency: int = 10
    episode_seconds: float = 20.0
    highway_config: Mapping[str, Any] = field(default_factory=dict)
    surface_resolution: float = 0.1  # metres per cell of the road-surface map
    far_distance: float = 1000.0  # camera far plane; sky depth, as CARLA's depth camera saturates at 1 km
    labels: LabelConfig | None = field(default_factory=lambda: _default_labels())  # None: no boxes in info
    traffic: str = "fast"  # "fast": fog_gym.world.traffic core; "reference": highway-env's own Python path
    hazards: HazardConfig | None = None  # stalled vehicles ahead of the ego (the RL hazard preset)
    #: "episode": road surface and props built around each episode's start from its seed (FogDrive-v0, datasets);
    #: "town": built once per town and reused by every episode (resets in milliseconds; the RL presets)
    static_world: str = "episode"
    geometry: str = "meshes"

    def __post_init__(self) -> None:
        if self.geometry not in GEOMETRIES:
            raise ValueError(f"geometry must be one of {GEOMETRIES}, got {self.geometry!r}")
        if self.town not in TOWNS:
            raise ValueError(f"town must be one of {TOWNS}, got {self.town!r}")
        check_traffic_mode(self.traffic)
        if self.static_world not in STATIC_WORLDS:
            raise ValueError(f"static_world must be one of {STATIC_WORLDS}, got {self.static_world!r}")
        if self.hazards is not None and not isinstance(self.hazards, HazardConfig):
            raise ValueError(f"hazards must be a HazardConfig or None, got {type(self.hazards).__name__}")
        if self.time_of_day not in TIMES_OF_DAY:
            raise ValueError(f"time_of_day must be one of {TIMES_OF_DAY}, got {self.time_of_day!r}")
        if not isinstance(self.rig, RigConfig):
            raise ValueError(f"rig must be a RigConfig, got {type(self.rig).__name__}")
        for name in ("simulation_frequency", "keyframe_frequency"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v <= 0:
                raise ValueError(f"{name} must be a positive integer (Hz), got {v!r}")
        if self.simulation_frequency % self.keyframe_frequency:
            raise ValueError(
                "simulation_frequency must be a multiple of keyframe_frequency, got "
                f"{self.simulation_frequency} and {self.keyframe_frequency}"
            )
        secs = finite("episode_seconds", self.episode_seconds)
        if secs <= 0:
            raise ValueError(f"episode_seconds must be > 0, got {self.episode_seconds!r}")
        if not isinstance(self.highway_config, Mapping):
            raise ValueError(f"highway_config must be a mapping, got {type(self.highway_config).__name__}")
        res = finite("surface_resolution", self.surface_resolution)
        if not 0.01 <= res <= 1.0:
            raise ValueError(f"surface_resolution must lie in [0.01, 1.0] metres, got {self.surface_resolution!r}")
        far = finite("far_distance", self.far_distance)
        if far <= 1.0:
            raise ValueError(f"far_distance must be > 1 m, got {self.far_distance!r}")

        if self.labels is not None and not isinstance(self.labels, LabelConfig):
            raise ValueError(f"labels must be a LabelConfig or None, got {type(self.labels).__name__}")
        if self.labels is not None and self.labels.visibility == "lidar" and self.rig.semantic_lidar is None:
            raise ValueError(
                "labels: visibility='lidar' (FogDrive's rule) needs the semantic LiDAR in the rig; "
                "use visibility='camera', or labels=None for no boxes"
            )

    @property
    def episode_steps(self) -> int:
        """Env steps (keyframes) per episode."""
        return int(round(self.episode_seconds * self.keyframe_frequency))

    @property
    def town_number(self) -> int:
        """FogDrive town number (``T<n>``), the 1-based position in :data:`TOWNS`."""
        return TOWNS.index(self.town) + 1


def _default_labels():

    return LabelConfig()
