"""fog-gym: a Gymnasium environment for driving perception under graded, physically calibrated fog.

``import fog_gym`` registers the environments (:mod:`fog_gym.envs`). The package is laid out along the data path:
:mod:`~fog_gym.world` (towns, traffic, scenery, the Scene) → :mod:`~fog_gym.sensors` (each sensor with its config)
→ :mod:`~fog_gym.render` (the cameras' rasteriser and night lighting) → :mod:`~fog_gym.fog` (physics, models,
curricula) → :mod:`~fog_gym.perception` → :mod:`~fog_gym.labels` → :mod:`~fog_gym.dataset` (the FogDrive layout) /
:mod:`~fog_gym.envs` (the registered environments) / :mod:`~fog_gym.rl`; :mod:`~fog_gym.experiments` holds the
studies, :mod:`~fog_gym.viz` pictures and the viewer, :mod:`~fog_gym.cli` the ``fog-gym`` command.

Example:
    >>> import gymnasium as gym, fog_gym
    >>> "FogDrive-v0" in gym.registry
    True
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

from fog_gym._memory import tune_malloc

tune_malloc()

import fog_gym.envs  # noqa: E402,F401  (registers the environments)
from fog_gym._version import __version__  # noqa: E402
from fog_gym.geometry import Pose  # noqa: E402
from fog_gym.sensors import CAMERA_NAMES, CameraConfig, LidarConfig, RadarConfig, RigConfig, SemanticLidarConfig  # noqa: E402
from fog_gym.channels.packing import unpack_points  # noqa: E402
from fog_gym.world.hazards import HazardConfig  # noqa: E402
from fog_gym.world.towns import TIMES_OF_DAY, TOWNS  # noqa: E402

__all__ = [
    "CAMERA_NAMES", "TIMES_OF_DAY", "TOWNS", "CameraConfig", "FogDriveConfig", "HazardConfig", "Pose", "RigConfig",
    "FogDriveEnv", "LidarConfig", "RadarConfig", "SemanticLidarConfig", "unpack_points", "accelerate", "__version__",
]  # fmt: skip

_LAZY = {"FogDriveEnv": "fog_gym.envs.fogdrive", "FogDriveConfig": "fog_gym.envs.config",
         "accelerate": "fog_gym.world.traffic"}  # fmt: skip


def __getattr__(name: str):
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'fog_gym' has no attribute {name!r}")


#: Module paths of earlier releases → where the module lives now. ``import fog_gym.env`` (and ``from fog_gym.viewer
#: import view_dataset``, unpickling an object saved under an old path, …) keeps working with a DeprecationWarning.
MOVED = {
    "fog_gym.env": "fog_gym.envs.fogdrive",
    "fog_gym.make": "fog_gym.envs.presets",
    "fog_gym.config": "fog_gym.envs.config",
    "fog_gym.viewer": "fog_gym.viz.viewer",
    "fog_gym.minari": "fog_gym.rl.minari",
    "fog_gym.sb3": "fog_gym.rl.sb3",
    "fog_gym.curriculum": "fog_gym.fog.schedules",
    "fog_gym.fog_models": "fog_gym.fog.models",
    "fog_gym.points": "fog_gym.dataset.packing",
    "fog_gym.lidar": "fog_gym.sensors.lidar",
    "fog_gym.scene": "fog_gym.world.scene",
    "fog_gym.scenery": "fog_gym.world.scenery",
    "fog_gym.primitives": "fog_gym.world.primitives",
    "fog_gym.traffic": "fog_gym.world.traffic",
    "fog_gym.traffic.core": "fog_gym.world.traffic.core",
    "fog_gym.traffic.vehicles": "fog_gym.world.traffic.vehicles",
    "fog_gym.audit": "fog_gym.experiments.audit",
    "fog_gym.perception.dehaze": "fog_gym.dehaze.classical",
    "fog_gym.perception.aodnet": "fog_gym.dehaze.aodnet",
    "fog_gym.detect3d": "fog_gym.experiments.detection3d",
    "fog_gym.detect2d": "fog_gym.experiments.defog.yolo",
}


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports a moved module path as the module that replaced it (the same module object)."""

    def find_spec(self, fullname, path, target=None):
        if fullname not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        new = MOVED[spec.name]
        warnings.warn(f"{spec.name} moved to {new}; import it from there", DeprecationWarning, stacklevel=4)
        return importlib.import_module(new)

    def exec_module(self, module):
        pass


if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
    sys.meta_path.append(_MovedFinder())
