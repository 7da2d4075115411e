"""Fog models: the protocol, the registry that maps a sensor kind to its model, and the two built-in models.

A fog model turns one clean channel into its fogged versions, one per :class:`~fog_gym.fog.physics.FogLevel`; the
physics stays in :mod:`fog_gym.fog.camera` and :mod:`fog_gym.fog.lidar`. :class:`~fog_gym.wrappers.FogWrapper` asks
:func:`model_for` for the model of each sensor of the rig (cameras → :class:`Koschmieder`, LiDAR → :class:`Hahner`);
a kind without a model (semantic LiDAR, radar) keeps its clean data. A new model is a class with ``name`` and
``apply`` registered for a sensor kind with :func:`register_model`.

Example:
    >>> model_for("camera").name, model_for("lidar").name, model_for("radar")
    ('koschmieder', 'hahner', None)
    >>> obs = {"C": np.zeros((2, 2, 3), np.uint8), "C_DEPTH": np.full((2, 2), 1000.0, np.float32)}
    >>> ctx = FogContext(intrinsics={"C": np.array([[1.0, 0, 1], [0, 1.0, 1], [0, 0, 1]])}, airlight={"C": np.full(3, 200.0)})
    >>> int(Koschmieder().apply(obs, "C", [parse_fog("dense")], ctx)["dense"].max())  # the sky takes the airlight
    200
    >>> obs = {"LIDAR_TOP": np.array([[10.0, 0, 0, 1.0], [0, 0, 0, 0]], np.float32)}
    >>> lv = parse_fog("clear")
    >>> Hahner().apply(obs, "LIDAR_TOP", [lv], FogContext(rngs={lv.name: np.random.default_rng(0)}))["clear"].shape
    (2, 4)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import ClassVar, Protocol, runtime_checkable

import numpy as np

from fog_gym.fog.camera import fog_field_images, fog_images
from fog_gym.fog.depth import field_pose
from fog_gym.fog.lidar import fog_lidar_into
from fog_gym.fog.lidar_field import fog_lidar_field
from fog_gym.fog.physics import FogLevel, parse_fog  # noqa: F401  (parse_fog: the example)
from fog_gym.channels.packing import pack_points, unpack_points


@dataclass(frozen=True)
class FogContext:
    """What a model may need beyond the observation: per-camera intrinsics and atmospheric light, one random
    generator per level name, whether the scene is at night, and the LiDAR fog's noise scale [m]."""

    intrinsics: Mapping[str, np.ndarray] = field(default_factory=dict)
    airlight: Mapping[str, np.ndarray] = field(default_factory=dict)
    rngs: Mapping[str, np.random.Generator] = field(default_factory=dict)
    night: bool = False
    lidar_noise: float = 10.0
    #: The LiDAR's atmosphere attenuation rate when its intensities follow the "reflectance" model (None: CARLA's)
    lidar_reflectance: float | None = None
    #: Fog fields (:mod:`fog_gym.fog.fields`): each fogged sensor's 4×4 pose (a camera's optical frame → world, a
    #: LiDAR's frame → world), the field frame ``(x0, y0, heading)`` and the time since reset [s]
    poses: Mapping[str, np.ndarray] = field(default_factory=dict)
    frame: tuple[float, float, float] = (0.0, 0.0, 0.0)
    time: float = 0.0
    #: The LiDAR's return mode (:mod:`fog_gym.fog.returns`): "strongest", "last" or "dual"
    lidar_returns: str = "strongest"
    #: Cameras that record with noise (:mod:`fog_gym.sensors.camera_effects`): their noise-free images (fog is
    #: added to the light, before the sensor), ``record(channel, rgb, variant)`` that turns a fogged image into
    #: what the camera records, and each level's variant number (its own noise draws)
    clean_rgb: Mapping[str, np.ndarray] = field(default_factory=dict)
    record: Callable[[str, np.ndarray, int], np.ndarray] | None = None
    variants: Mapping[str, int] = field(default_factory=dict)
    #: Point channels the env packed itself (``FogDriveEnv.point_rows``): how many leading rows are points, the
    #: rest zero. The LiDAR fog reads them without scanning the channel; any other channel is unpacked.
    point_rows: Mapping[str, int] = field(default_factory=dict)


@runtime_checkable
class FogModel(Protocol):
    """Fog for one sensor kind."""

    name: ClassVar[str]

    def apply(self, obs: Mapping[str, np.ndarray], channel: str, levels: Sequence[FogLevel],
              context: FogContext) -> dict[str, np.ndarray]:  # fmt: skip
        """``{level name: fogged array of channel}``, shaped as ``obs[channel]``; clean data are never changed."""


#: Sensor kind → fog model instance (see :func:`register_model`).
MODELS: dict[str, FogModel] = {}


def register_model(kind: str):
    """Class decorator: the model fogs every sensor of ``kind`` (``camera``, ``lidar``, …)."""
    if not isinstance(kind, str) or not kind:
        raise ValueError(f"kind must be a sensor kind such as 'camera' or 'lidar', got {kind!r}")

    def deco(cls: type) -> type:
        MODELS[kind] = cls()
        return cls

    return deco


def model_for(kind: str) -> FogModel | None:
    """The fog model of a sensor kind, or None when the kind is not fogged (the built-in models register when
    :mod:`fog_gym.fog.models` is imported)."""
    return MODELS.get(kind)


@register_model("camera")
class Koschmieder:
    """Koschmieder fog for cameras (:func:`fog_gym.fog.camera.fog_images`; at night with the glow of
    :func:`fog_gym.fog.glow.add_glows`); needs the camera's ``C_DEPTH`` beside its RGB, its intrinsics and its
    atmospheric light from the context."""

    name = "koschmieder"

    def apply(self, obs, channel, levels, context):
        rgb, depth, K = context.clean_rgb.get(channel, obs[channel]), obs[f"{channel}_DEPTH"], context.intrinsics[channel]
        out = {}
        flat = [lv for lv in levels if lv.is_homogeneous]
        if flat:
            images = fog_images(rgb, depth, K, [lv.alpha for lv in flat], context.airlight[channel], validate=False,
                                glow=context.night)  # fmt: skip
            out.update({lv.name: img for lv, img in zip(flat, images)})
        shaped = [lv for lv in levels if not lv.is_homogeneous]
        if shaped:
            pose = field_pose(context.poses[channel], context.frame)
            images = fog_field_images(rgb, depth, K, shaped, context.airlight[channel], pose, context.time,
                                      validate=False, glow=context.night)  # fmt: skip
            out.update({lv.name: img for lv, img in zip(shaped, images)})
        if context.record is not None and channel in context.clean_rgb:
            return {lv.name: context.record(channel, out[lv.name], context.variants[lv.name]) for lv in levels}
        return {lv.name: out[lv.name] for lv in levels}


@register_model("lidar")
class Hahner:
    """Hahner et al. fog for LiDAR point clouds (:func:`fog_gym.fog.lidar.fog_lidar`) on the packed observation; each
    level draws from its own generator (``context.rngs[level name]``)."""

    name = "hahner"

    def apply(self, obs, channel, levels, context):
        from fog_gym.fog.returns import apply_returns, field_tau

        mode = context.lidar_returns
        # the clean sweep read in place (the fog only reads it); in dual mode without its return column (all 0),
        # which the return rule writes anew. x, y, z, intensity feed the physics; further columns (a sweep's time)
        # ride along with each beam
        n = context.point_rows.get(channel)
        rows = unpack_points(obs, channel, copy=False) if n is None else obs[channel][:n]
        width = rows.shape[1] - (mode == "dual")
        clean = rows if mode != "dual" else rows[:, :width]
        capacity = obs[channel].shape[0]
        out = {}
        for lv in levels:
            if not lv.is_homogeneous:
                clean = np.ascontiguousarray(clean)  # the field kernels read whole rows
            if lv.is_homogeneous:  # one pass of the fog and the return rule writes the packed channel
                packed = np.empty(obs[channel].shape, np.float32)
                fog_lidar_into(rows, lv, context.rngs[lv.name], packed, mode, context.lidar_noise,
                               context.lidar_reflectance, columns=width)  # fmt: skip
                out[lv.name] = packed
            else:  # a fog field: the local extinction along each beam
                pose = field_pose(context.poses[channel], context.frame)
                fogged = fog_lidar_field(clean, lv, context.rngs[lv.name], pose, context.time, context.lidar_noise,
                                         context.lidar_reflectance)  # fmt: skip
                tau = None if mode == "strongest" else field_tau(clean, lv, pose, context.time)
                if mode == "strongest":
                    out[lv.name] = pack_points(fogged, capacity)
                else:  # the return rule writes the packed channel itself
                    out[lv.name] = apply_returns(clean, fogged, tau, mode, capacity=capacity)
        return out
