"""The cameras' configuration: FogDrive's camera names and poses and :class:`CameraConfig` (no rig, no sensors).

Its own module so that the dataset layout and the camera sensor can name the FogDrive cameras without the rig
(:mod:`fog_gym.config` re-exports everything here).

Example:
    >>> CameraConfig("CAM_FRONT_NARROW", FOGDRIVE_CAMERA_POSES["CAM_FRONT"], 64, 48, fov=40.0).width
    64
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

from fog_gym.pose import Pose
from fog_gym.pose import finite as _finite

#: FogDrive camera channel names (Table 3), in the order the rig lists them.
CAMERA_NAMES: tuple[str, ...] = ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT")
_NAME_RE = re.compile(r"[A-Z][A-Z0-9_]*")


def check_sensor_name(name: Any) -> str:
    """A sensor (and channel) name is upper case: letters, digits, underscores, starting with a letter.

    >>> check_sensor_name("RADAR_BACK")
    'RADAR_BACK'
    >>> check_sensor_name("radar back")
    Traceback (most recent call last):
    ...
    ValueError: sensor name must be an upper-case channel name like 'RADAR_BACK', got 'radar back'
    """
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name):
        raise ValueError(f"sensor name must be an upper-case channel name like 'RADAR_BACK', got {name!r}")
    return name


@dataclass(frozen=True)
class CameraConfig:
    """One pinhole camera; RGB, depth, semantic and instance buffers share its pose and intrinsics. Its name is
    its RGB channel (a FogDrive name of :data:`CAMERA_NAMES`, or any upper-case name for an added camera).

    >>> CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), 640, 480).intrinsic()[0, 0].round(2)
    np.float64(268.51)
    """

    name: str
    pose: Pose
    width: int = 1280
    height: int = 960
    fov: float = 100.0  # horizontal field of view, degrees

    def __post_init__(self) -> None:
        check_sensor_name(self.name)  # the FogDrive cameras are CAMERA_NAMES; an added camera takes any such name
        object.__setattr__(self, "pose", Pose.coerce(self.pose))
        for attr in ("width", "height"):
            value = getattr(self, attr)
            if isinstance(value, bool) or not isinstance(value, (int,)) and not (
                isinstance(value, float) and value.is_integer()
            ):
                raise ValueError(f"resolution {attr} must be a positive integer, got {value!r}")
            if int(value) <= 0:
                raise ValueError(f"resolution {attr} must be a positive integer, got {value!r}")
            object.__setattr__(self, attr, int(value))
        fov = _finite("fov", self.fov)
        if not 0.0 < fov < 180.0:
            raise ValueError(f"fov must lie in the open interval (0, 180) degrees, got {self.fov!r}")
        object.__setattr__(self, "fov", fov)

    def intrinsic(self):
        from fog_gym.geometry import intrinsic_matrix

        return intrinsic_matrix(self.width, self.height, self.fov)


#: Camera poses of FogDrive Table 2.
FOGDRIVE_CAMERA_POSES: dict[str, Pose] = {
    "CAM_FRONT": Pose(1.8, 0.0, 1.2, 0.0, 0.0, 0.0),
    "CAM_BACK": Pose(-2.4, 0.0, 1.2, 0.0, 0.0, 180.0),
    "CAM_LEFT": Pose(0.5, -0.7, 1.5, 0.0, 0.0, -100.0),
    "CAM_RIGHT": Pose(0.5, 0.7, 1.5, 0.0, 0.0, 100.0),
}


