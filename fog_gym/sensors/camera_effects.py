"""What a real camera does to the rendered light: motion blur over the exposure, then sensor noise, per frame.

:class:`CameraEffects` holds, for the cameras of a rig that have a :class:`~fog_gym.sensors.camera_noise.CameraNoise`,
the frame's noise tables (one per camera: the gain follows that camera's auto-exposure), image flows (with motion
blur) and noise keys. :meth:`CameraEffects.prepare` sets them up once per frame; :meth:`CameraEffects.apply` turns a
noise-free RGB image of the frame — the clean one or any fogged variant (fog is light in the scene, so it comes
before the sensor) — into what the camera records, each variant with its own draws from the episode's one seed.

Example:
    >>> from fog_gym.sensors.camera import CameraConfig
    >>> from fog_gym.geometry import Pose
    >>> fx = CameraEffects([CameraConfig("CAM_FRONT", Pose(1.8, 0, 1.2), 8, 6, noise="default")])
    >>> img = np.full((6, 8, 3), 100, np.uint8)
    >>> fx.prepare(seed=7, tick=0, exposure={"CAM_FRONT": 1.0}, night=False)
    >>> a, b = fx.apply("CAM_FRONT", img, 0), fx.apply("CAM_FRONT", img, 1)
    >>> bool((a != img).any()), bool((a != b).any()), abs(float(a.mean()) - 100) < 1
    (True, True, True)
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from fog_gym.sensors.camera_noise import CameraNoise, add_noise, frame_key, noise_table
from fog_gym.sensors.motion_blur import blur_motion, image_flow

#: Noise tables kept per (sensor, gain, night) (day frames all share gain 1).
TABLE_CACHE = 32


class CameraEffects:
    """Motion blur and noise for the cameras of a rig whose config has ``noise`` (module docstring)."""

    def __init__(self, cameras: Sequence[Any]) -> None:
        self.noise: dict[str, CameraNoise] = {c.name: c.noise for c in cameras if getattr(c, "noise", None) is not None}
        self._index = {c.name: i for i, c in enumerate(cameras)}
        self._tables: OrderedDict[tuple, np.ndarray] = OrderedDict()
        self._frame: dict[str, tuple[np.ndarray, int, np.ndarray | None]] = {}

    def __bool__(self) -> bool:
        return bool(self.noise)

    def table(self, noise: CameraNoise, gain: float, night: bool) -> np.ndarray:
        key = (noise, float(gain), bool(night))
        t = self._tables.get(key)
        if t is None:
            t = self._tables[key] = noise_table(noise, gain, night)
            if len(self._tables) > TABLE_CACHE:
                self._tables.popitem(last=False)
        else:
            self._tables.move_to_end(key)
        return t

    def prepare(self, seed: int, tick: int, exposure: Mapping[str, float], night: bool,
                flows: Mapping[str, Any] | None = None) -> None:  # fmt: skip
        """Set up the frame ``tick`` of the episode whose noise seed is ``seed``: each camera's table from its
        auto-exposure gain ``exposure[name]``; ``flows[name]`` the arguments of
        :func:`~fog_gym.sensors.motion_blur.image_flow` but the exposure, for cameras with motion blur."""
        self._frame = {}
        for name, noise in self.noise.items():
            flow = None
            if noise.motion_blur and flows is not None and name in flows:
                flow = image_flow(*flows[name], noise.exposure_s[1] if night else noise.exposure_s[0])
            self._frame[name] = (self.table(noise, exposure.get(name, 1.0), night),
                                 frame_key(seed, tick, self._index[name], 0), flow)  # fmt: skip

    def apply(self, name: str, rgb: np.ndarray, variant: int) -> np.ndarray:
        """The recorded image of noise-free ``rgb`` of camera ``name`` in this frame; ``variant`` 0 the clean frame,
        another integer a fogged one (its own draws). Cameras without noise get ``rgb`` back."""
        if name not in self._frame:
            return rgb
        table, key, flow = self._frame[name]
        if flow is not None:
            rgb = blur_motion(rgb, flow)
        return add_noise(rgb, table, frame_key(key, variant, 0, 0) if variant else key)
