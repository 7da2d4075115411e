"""Fog on the data people already have: fog-gym's calibrated fog applied to real LiDAR scans and camera images.

The physics is the simulator's own — Hahner et al. for LiDAR (:func:`fog_gym.fog.fog_lidar`,
:func:`fog_gym.fog.lidar_field.fog_lidar_field`), Koschmieder for cameras (:func:`fog_gym.fog.fog_image`,
:func:`fog_gym.fog.camera.fog_field_images`) — with no second copy of it. What real data needs besides:

* a **LiDAR profile** (:mod:`~fog_gym.augment.profiles`): how a sensor's file stores intensity and where the sensor
  sits above the road;
* **dense depth** for images (:mod:`~fog_gym.augment.depth`): the scan projected with the calibration and completed
  by Ku et al.'s classical method, the sky found in the image;
* a **field frame**: fog fields (banks, ground fog; :mod:`fog_gym.fog.fields`) are laid out in a frame whose x axis
  is the heading along which a bank's ``start`` is measured and whose z = 0 is the road. By default that frame is
  the LiDAR's own (x forward, z up) moved down by the profile's mount height; ``sensor_to_field`` (4 × 4) places the
  sensor otherwise (nuScenes' ``calibrated_sensor``, LiDAR → ego, makes it the ego frame).

``fog`` is anything the environments' ``fog=`` takes: a level name (``"light"``, ``"moderate"``, ``"dense"``,
``"clear"``), a visibility in metres, or a fog field (``FogBank``, ``HeightFog``, their sums).

Example:
    >>> pts = np.array([[100.0, 0, 0, 0.67], [10.0, 0, 0, 0.96]], np.float32)  # KITTI: reflectance in [0, 1]
    >>> out = fog_points(pts, "dense", profile="kitti", rng=np.random.default_rng(0))
    >>> bool(np.linalg.norm(out[0, :3]) < 10), out[1, :3].tolist()  # the far point is fog, the near one stays
    (True, [10.0, 0.0, 0.0])
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.augment.depth import SKY_M, above_horizon, complete_depth, project_points
from fog_gym.augment.profiles import PROFILES, LidarProfile, get_profile, load_profile

__all__ = ["PROFILES", "SKY_M", "LidarProfile", "above_horizon", "as_fog", "complete_depth", "fog_image", "fog_points",
           "get_profile", "image_depth", "load_profile", "project_points"]  # fmt: skip


def as_fog(fog: Any) -> Any:
    """A fog level or field from what ``fog=`` accepts (a level name, metres, a :class:`~fog_gym.fog.physics.FogField`)."""
    from fog_gym.fog.physics import FogField, parse_fog

    if isinstance(fog, FogField):
        return fog
    return parse_fog(fog)


def _field_pose(sensor_to_field: np.ndarray) -> np.ndarray:
    from fog_gym.fog.depth import field_pose

    m = np.asarray(sensor_to_field, np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise ValueError(f"sensor_to_field must be a finite 4 × 4 transform, got shape {m.shape}")
    return field_pose(m, (0.0, 0.0, 0.0))


def fog_points(points: np.ndarray, fog: Any, profile: str | Path | LidarProfile = "fogdrive",
               rng: np.random.Generator | None = None, sensor_to_field: np.ndarray | None = None,
               time: float = 0.0) -> np.ndarray:  # fmt: skip
    """Fog on a LiDAR scan: ``points`` ``(N, ≥4)`` — x, y, z [m] in the sensor frame and the intensity in the
    profile's scale, any further columns (ring, time) kept — → the same shape and dtype. Each point stays (its
    intensity attenuated) or becomes a return of the fog on its own ray, by Hahner et al.'s rule; ``rng`` draws the
    fog returns' range noise (default: seeded 0). ``sensor_to_field`` and ``time`` place a fog field (module
    docstring; homogeneous fog ignores them)."""
    from fog_gym.fog.lidar import fog_lidar
    from fog_gym.fog.lidar_field import fog_lidar_field

    prof = get_profile(profile)
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] < 4:
        raise ValueError(f"points must be an (N, >=4) array (x, y, z, intensity, ...), got shape {pts.shape}")
    if not np.issubdtype(pts.dtype, np.number) or not np.isfinite(pts[:, :4].astype(np.float64)).all():
        raise ValueError("points must be finite numbers (x, y, z, intensity)")
    level = as_fog(fog)
    rng = rng if rng is not None else np.random.default_rng(0)
    work = np.empty((len(pts), 4), np.float32)
    work[:, :3] = pts[:, :3]
    work[:, 3] = prof.to_model(pts[:, 3])
    if level.is_homogeneous:
        from fog_gym.fog.physics import FogLevel, parse_fog

        out = fog_lidar(work, level if isinstance(level, FogLevel) else parse_fog(level.visibility_m), rng, prof.noise_m)
    else:
        pose = _field_pose(prof.sensor_to_field() if sensor_to_field is None else sensor_to_field)
        out = fog_lidar_field(work, level, rng, pose, time, prof.noise_m)
    result = pts.copy()
    moved = (out[:, :3] != work[:, :3]).any(axis=1)  # fog returns: write the new position; kept points stay bit-exact
    result[moved, :3] = out[moved, :3].astype(result.dtype)
    result[:, 3] = prof.from_model(out[:, 3]).astype(result.dtype)
    return result


def image_depth(size: tuple[int, int], K: np.ndarray, points: np.ndarray, T_cam_lidar: np.ndarray,
                up: tuple[float, float, float] = (0.0, 0.0, 1.0), rgb: np.ndarray | None = None,
                sky: str = "image") -> np.ndarray:  # fmt: skip
    """Dense planar depth of a ``size`` = (W, H) image from a LiDAR scan: projected, completed (Ku et al.); below the
    LiDAR's horizontal plane, where no return reaches, the flat ground at the scan's road height (the 2nd percentile
    of the points' heights within 30 m: a LiDAR above the camera misses the road right in front of it); above it,
    with ``sky="image"`` and the image ``rgb``, the image's sky (:func:`~fog_gym.augment.depth.sky_mask`) and
    for the rest each column's top depth carried upward (objects above the scan), with ``sky="horizon"`` (or no
    image) everything sky (:mod:`fog_gym.augment.depth`)."""
    from fog_gym.augment.depth import check_sky_rule, ground_depth, reached_by_scan, sky_mask

    check_sky_rule(sky)
    if rgb is not None and np.shape(rgb)[:2] != (size[1], size[0]):
        raise ValueError(f"rgb must be an image of size (W, H) = {tuple(size)}, got shape {np.shape(rgb)}")
    sparse = project_points(points, K, T_cam_lidar, size)
    p = np.asarray(points, np.float64)[:, :3]
    upv = np.asarray(up, np.float64)
    near = np.linalg.norm(p, axis=1) < 30.0
    heights = p[near] @ upv if near.any() else p @ upv
    ground = ground_depth(K, T_cam_lidar, size, float(np.percentile(heights, 2)), up) if len(heights) else None
    above = above_horizon(K, T_cam_lidar, size, up)
    if rgb is None or sky == "horizon":
        return complete_depth(sparse, above, ground=ground)
    sky_px = sky_mask(rgb, above & ~reached_by_scan(sparse))
    return complete_depth(sparse, sky_px, ground=ground, extend=above)


def fog_image(rgb: np.ndarray, K: np.ndarray, fog: Any, depth: np.ndarray | None = None, points: np.ndarray | None = None,
              T_cam_lidar: np.ndarray | None = None, airlight: np.ndarray | None = None,
              rng: np.random.Generator | None = None, camera_to_field: np.ndarray | None = None,
              profile: str | Path | LidarProfile = "fogdrive", time: float = 0.0, glow: bool = False,
              sky: str = "image") -> np.ndarray:  # fmt: skip
    """Koschmieder fog on a uint8 RGB image with intrinsic ``K``: planar ``depth`` [m] as given (stereo, a network, a
    simulator), or completed from a LiDAR scan ``points`` in the LiDAR frame with the LiDAR → camera transform
    ``T_cam_lidar`` (:func:`image_depth`, whose ``sky`` rule is passed on). ``airlight`` (RGB, 0–255) defaults to
    the image's own estimate (dark channel, as fog-gym's day frames). Camera fog has no random part: ``rng`` is
    accepted so that one stream can be passed to both sensors, and is not drawn from. A fog field needs the camera's
    place in the field frame: ``camera_to_field``, or the LiDAR's (the profile's default) composed with
    ``T_cam_lidar``. ``glow`` (for night frames) adds the glow that lit fog spreads around the image's bright
    sources (:func:`fog_gym.fog.add_glow`: lamps and headlights, found in the image with their depth), as fog-gym's
    night frames have."""
    from fog_gym.dehaze.classical import check_image
    from fog_gym.fog.camera import atmospheric_light, fog_field_images, fog_images

    from fog_gym.augment.depth import check_sky_rule

    img = check_image(rgb, "rgb")
    check_sky_rule(sky)
    h, w = img.shape[:2]
    k, t = _check_calibration_pair(K, T_cam_lidar)
    if depth is None:
        if points is None or t is None:
            raise ValueError("fog_image needs a depth map, or LiDAR points with T_cam_lidar to complete one")
        depth = image_depth((w, h), k, points, t, rgb=img, sky=sky)
    d = np.asarray(depth, np.float32)
    if d.shape != (h, w):
        raise ValueError(f"depth must be (H, W) = {(h, w)} like the image, got {d.shape}")
    a = atmospheric_light(img) if airlight is None else np.asarray(airlight, np.float64)
    level = as_fog(fog)
    if level.is_clear:
        return img.copy()
    if level.is_homogeneous:
        return fog_images(img, d, k, [level.alpha], a, glow=glow)[0]
    if camera_to_field is None:
        if t is None:
            raise ValueError("a fog field on an image needs camera_to_field, or T_cam_lidar to place the camera")
        camera_to_field = get_profile(profile).sensor_to_field() @ np.linalg.inv(t)
    return fog_field_images(img, d, k, [level], a, _field_pose(camera_to_field), time, glow=glow)[0]


def _check_calibration_pair(K: np.ndarray, T: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    from fog_gym.augment.depth import _check_calibration

    return _check_calibration(K, T)
