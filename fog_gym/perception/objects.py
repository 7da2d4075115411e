"""Perceived objects: what the fogged sensors detect, per sensor and fused, as a highway-env Kinematics-style array.

:class:`ObjectsConfig` is the detection rig and its rules; :func:`perceive` runs the detection kernels
(:mod:`fog_gym.perception.kernels`) for many worlds of a :class:`~fog_gym.world.traffic.native.NativeTraffic` in one
call and fuses the results into the observation and the per-sensor detection lists.

**Detection rules** (defaults):

* LiDAR: ≥ ``min_points`` = 5 returns that survive CARLA's drop-off and the Hahner fog model on the vehicle. The
  detection LiDAR is the FogDrive roof LiDAR's geometry made denser where it matters: 64 channels over
  [−15°, +5°], 2048 beams per channel and turn (0.18°), 120 m, so a car's rear is detected to ≈ 100 m in clear air.
* Camera: ≥ ``min_pixels`` = 10 visible pixels in its instance mask and a Weber contrast ≥ ``min_contrast`` = 5 %
  (the contrast that defines visibility) against a ring of pixels around it, in the fogged image of a 640 × 480,
  100° camera at the front camera's pose (a car at 100 m covers ≈ 19 pixels).
* Radar: ≥ 1 of the radar's 900 rays per tick (FogDrive's 18 000 points/s at 20 Hz, 150 m, 120° × 30°) lands on it.

**Reported values** (ego frame: x ahead, y right, metres; seeded noise from the episode, never from the fog):

* LiDAR: the centroid of the surviving returns + N(0, 0.05 m) per axis; camera: bearing of the visible pixels + N(0, 0.002 rad) and range ``f · H / h`` from the box's
  visible height ``h`` in pixels and the class's typical height ``H`` (car 1.5 m, bigger car 2.2 m, truck 3.4 m),
  times 1 + N(0, 0.05); radar: mean range + N(0, 0.25 m) and azimuth + N(0, 0.01 rad) of its detections. Each
  measures the vehicle's near surface: the reported position is that point moved half a typical car length
  (:data:`HALF_LENGTH` = 2.3 m) further along its bearing, a box fit with a car's size.
* Velocity (relative to the ego): LiDAR and camera from an alpha-beta tracker over their own reported positions
  (β = 0.3; 0 on the step a vehicle is first detected); radar: the mean radial velocity + N(0, 0.1 m/s) along the bearing.
* Fused: every vehicle some sensor detected, position and velocity the inverse-variance mean of the sensors'
  (σ: LiDAR 0.1 m, camera 0.5 m + 5 % of the range, radar 0.5 m), one flag per sensor.

**Observation** ``(max_objects, 6 + len(sensors))`` float32: row 0 the ego (presence 1, x 0, y its lateral position on
the road, vx, vy its velocity, lane its lane across the road from −1 (leftmost) to +1 (rightmost), flags 1), then
the fused objects nearest first (reported distance), unused rows zero. Features presence, x, y, vx, vy, lane (the
lane the reported position falls in, relative to the ego's, / 2: −0.5 one lane left, +0.5 one lane right) and one
flag per sensor in :data:`SENSORS` order; x, y, vx, vy normalised as highway-env's Kinematics observation
(x ∈ ±200 m, y ∈ ±4·lanes m, vx, vy ∈ ±80 m/s mapped to [−1, 1], clipped).

Example:
    >>> ObjectsConfig(sensors=("radar", "lidar")).sensors, ObjectsConfig().features
    (('lidar', 'radar'), ('presence', 'x', 'y', 'vx', 'vy', 'lane', 'camera', 'lidar', 'radar'))
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit, prange

from fog_gym.checks import finite
from fog_gym.perception import kernels as PK

#: Sensor kinds of the perceived-objects observation, in flag order.
SENSORS: tuple[str, ...] = ("camera", "lidar", "radar")
#: Layouts of the observation: the fused objects nearest first, or the nearest of them ahead and behind per lane.
LAYOUTS: tuple[str, ...] = ("list", "lanes")
#: The ``"lanes"`` layout's columns of a lane row (rows: ego, lane to the left, own lane, lane to the right).
LANE_FEATURES: tuple[str, ...] = ("exists", "ahead", "ahead_dv", "behind", "behind_dv")
#: How far the ``"lanes"`` layout looks ahead and behind [m] (an object further away counts as none).
LANE_AHEAD, LANE_BEHIND = 100.0, 50.0
#: A FogDrive class's typical height [m] (the camera's range prior).
CLASS_HEIGHT = {0: 1.5, 4: 2.2, 1: 3.4}
#: The velocity gain of the LiDAR's and camera's alpha-beta trackers (their velocity is their reports' rate of
#: change, predicted from the last step and corrected by β/dt times the innovation).
TRACK_BETA = 0.3
#: Half a typical car's length [m]: each sensor measures the vehicle's near surface; its reported position is that
#: point moved this much further along the bearing (a box fit with a car's size).
HALF_LENGTH = 2.3
MAX_SPEED = 40.0  # highway-env's Vehicle.MAX_SPEED: its Kinematics observation's ranges are multiples of it
SIGMA = {"lidar_xy": 0.05, "camera_bearing": 0.002, "camera_range": 0.05, "radar_range": 0.25, "radar_azimuth": 0.01,
         "radar_velocity": 0.1}  # fmt: skip


def _positive_int(name: str, value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


@dataclass(frozen=True)
class ObjectsConfig:
    """The detection rig and rules of the perceived-objects observation (see the module docstring)."""

    sensors: Sequence[str] = SENSORS
    max_objects: int = 8
    min_points: int = 5
    min_pixels: int = 10
    min_contrast: float = 0.05
    lidar_channels: int = 64
    lidar_beams: int = 2048
    lidar_fov: tuple[float, float] = (-15.0, 5.0)
    lidar_range: float = 120.0
    lidar_height: float = 2.0
    camera_size: tuple[int, int] = (640, 480)
    camera_fov: float = 100.0
    camera_pose: tuple[float, float] = (1.8, 1.2)  # metres ahead of the ego origin, height
    camera_range: float = 250.0
    radar_rays: int = 900
    radar_range: float = 150.0
    radar_fov: tuple[float, float] = (120.0, 30.0)
    radar_pose: tuple[float, float] = (2.0, 1.2)
    max_rays: int = 64  # rays cast per vehicle and sensor at most (strided beyond)
    layout: str = "list"  # the observation's layout: "list" (objects nearest first) or "lanes" (see LAYOUTS)
    #: Which LiDAR echo detects: "strongest" (the default: a return counts when it is the strongest echo, not the
    #: fog's) or "last" (opt-in: when the hard target reaches the detection floor, as a last-return LiDAR reports;
    #: fog_gym.fog.returns)
    lidar_returns: str = "strongest"
    flat: bool = False  # the observation as one flat vector (SB3's MlpPolicy and CleanRL take it without a warning)

    def __post_init__(self) -> None:
        if self.lidar_returns not in ("strongest", "last"):
            raise ValueError(f"lidar_returns must be strongest or last, got {self.lidar_returns!r}")
        if self.layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}, got {self.layout!r}")
        if not isinstance(self.flat, bool):
            raise ValueError(f"flat must be True or False, got {self.flat!r}")
        if isinstance(self.sensors, str) or not isinstance(self.sensors, Sequence):
            raise ValueError(f"sensors must be a non-empty subset of {SENSORS}, got {self.sensors!r}")
        unknown = [s for s in self.sensors if s not in SENSORS]
        if unknown or not self.sensors or len(set(self.sensors)) != len(self.sensors):
            raise ValueError(f"sensors must be a non-empty subset of {SENSORS} without repeats, got {self.sensors!r}")
        object.__setattr__(self, "sensors", tuple(s for s in SENSORS if s in self.sensors))
        for name in ("max_objects", "min_points", "min_pixels", "lidar_channels", "lidar_beams", "radar_rays",
                     "max_rays"):  # fmt: skip
            object.__setattr__(self, name, _positive_int(name, getattr(self, name)))
        if self.max_objects < 2:
            raise ValueError(f"max_objects must be an integer >= 2 (the ego's row and one object), got {self.max_objects!r}")
        if not 0.0 <= finite("min_contrast", self.min_contrast) < 1.0:
            raise ValueError(f"min_contrast must lie in [0, 1), got {self.min_contrast!r}")
        for name in ("lidar_range", "camera_range", "radar_range", "camera_fov"):
            if not finite(name, getattr(self, name)) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")

    @property
    def features(self) -> tuple[str, ...]:
        """The observation's columns (the ``"lanes"`` layout's ego row reads them as described in the module)."""
        if self.layout == "lanes":
            return LANE_FEATURES
        return ("presence", "x", "y", "vx", "vy", "lane", *self.sensors)

    @property
    def shape(self) -> tuple[int, int]:
        """The observation's shape: ``(max_objects, 6 + len(sensors))``, or ``(4, 5)`` for the ``"lanes"`` layout."""
        return (4, len(LANE_FEATURES)) if self.layout == "lanes" else (self.max_objects, len(self.features))

    @property
    def observation_shape(self) -> tuple[int, ...]:
        """The observation space's shape: :attr:`shape`, or its rows one after the other with ``flat``."""
        return (int(np.prod(self.shape)),) if self.flat else self.shape

    @property
    def sensor_mask(self) -> np.ndarray:
        return np.array([s in self.sensors for s in SENSORS])

    def lidar_elevations(self) -> np.ndarray:
        lo, hi = self.lidar_fov
        return np.radians(np.linspace(hi, lo, self.lidar_channels))

    @property
    def camera_focal(self) -> float:
        return self.camera_size[0] / 2.0 / math.tan(math.radians(self.camera_fov) / 2.0)


# outputs per world and slot: sensor index 0 camera, 1 lidar, 2 radar, 3 fused
CAM, LID, RAD, FUSED = 0, 1, 2, 3


@njit(cache=True, nogil=True)
def _fuse_world(n, f, classes, present, pos, vel, prev_present, prev_pos, prev_vel, lid_count, lid_cen, cam_pix, cam_con,
                cam_bear, cam_size, rad_hits, rad_rng, rad_az, rad_vr, mask, min_points, min_pixels, min_contrast,
                focal, cam_x, rad_x, lidar_h, key, tick, dt, lanes, layout, obs):  # fmt: skip
    """One world: detection flags, reported positions and velocities per sensor and fused, and the observation."""
    for j in range(n):
        for s in range(4):
            present[j, s] = False
    for j in range(1, n):
        vid = j
        if mask[LID] and lid_count[j] >= min_points:
            present[j, LID] = True
            pos[j, LID, 0] = lid_cen[j, 0] + 0.05 * PK.normal(key, tick, 5, vid, 0)
            pos[j, LID, 1] = lid_cen[j, 1] + 0.05 * PK.normal(key, tick, 5, vid, 1)
        if mask[CAM] and cam_pix[j] >= min_pixels and abs(cam_con[j]) >= min_contrast and cam_size[j] > 0:
            present[j, CAM] = True
            h_prior = 1.5 if classes[j] == 0 else (2.2 if classes[j] == 4 else 3.4)
            d = focal * h_prior / cam_size[j] * (1.0 + 0.05 * PK.normal(key, tick, 6, vid, 0))
            az = cam_bear[j] + 0.002 * PK.normal(key, tick, 6, vid, 1)
            pos[j, CAM, 0] = cam_x + d * math.cos(az)
            pos[j, CAM, 1] = d * math.sin(az)
        if mask[RAD] and rad_hits[j] >= 1:
            present[j, RAD] = True
            r = rad_rng[j] / rad_hits[j] + 0.25 * PK.normal(key, tick, 7, vid, 0)
            az = rad_az[j] / rad_hits[j] + 0.01 * PK.normal(key, tick, 7, vid, 1)
            vr = rad_vr[j] / rad_hits[j] + 0.1 * PK.normal(key, tick, 7, vid, 2)
            pos[j, RAD, 0] = rad_x + r * math.cos(az)
            pos[j, RAD, 1] = r * math.sin(az)
            vel[j, RAD, 0] = vr * math.cos(az)
            vel[j, RAD, 1] = vr * math.sin(az)
        for s in range(3):  # the measured surface point → the box centre: half a typical car length further
            if present[j, s]:
                r_s = math.hypot(pos[j, s, 0], pos[j, s, 1])
                if r_s > 1e-6:
                    pos[j, s, 0] += HALF_LENGTH * pos[j, s, 0] / r_s
                    pos[j, s, 1] += HALF_LENGTH * pos[j, s, 1] / r_s
        for s in (CAM, LID):  # an alpha-beta tracker's velocity: predicted from the last step, corrected by β/dt
            if present[j, s]:
                if prev_present[j, s]:
                    for ax in range(2):
                        innovation = pos[j, s, ax] - (prev_pos[j, s, ax] + prev_vel[j, s, ax] * dt)
                        vel[j, s, ax] = prev_vel[j, s, ax] + TRACK_BETA / dt * innovation
                else:
                    vel[j, s, 0] = 0.0
                    vel[j, s, 1] = 0.0
        # fusion: inverse-variance means over the sensors that saw it
        wsum = 0.0
        px = py = vx = vy = 0.0
        for s in range(3):
            if present[j, s]:
                rng_s = math.hypot(pos[j, s, 0], pos[j, s, 1])
                sig = 0.1 if s == LID else (0.5 + 0.05 * rng_s if s == CAM else 0.5)
                w = 1.0 / (sig * sig)
                wsum += w
                px += w * pos[j, s, 0]
                py += w * pos[j, s, 1]
                vx += w * vel[j, s, 0]
                vy += w * vel[j, s, 1]
        if wsum > 0:
            present[j, FUSED] = True
            pos[j, FUSED, 0], pos[j, FUSED, 1] = px / wsum, py / wsum
            vel[j, FUSED, 0], vel[j, FUSED, 1] = vx / wsum, vy / wsum
    for j in range(n):
        for s in range(4):
            prev_present[j, s] = present[j, s]
            prev_pos[j, s, 0] = pos[j, s, 0]
            prev_pos[j, s, 1] = pos[j, s, 1]
            prev_vel[j, s, 0] = vel[j, s, 0]
            prev_vel[j, s, 1] = vel[j, s, 1]
    if layout == 1:
        _lane_rows(n, f, present, pos, vel, lanes, obs)
    else:
        _list_rows(n, f, present, pos, vel, mask, lanes, obs)


@njit(cache=True, nogil=True)
def _list_rows(n, f, present, pos, vel, mask, lanes, obs):
    """The ``"list"`` observation: ego row, then the fused objects nearest first."""
    ey, eh = f[0, 1], f[0, 2]
    c0, s0 = math.cos(eh), math.sin(eh)
    m, nf = obs.shape
    for r in range(m):
        for c in range(nf):
            obs[r, c] = 0.0
    y_half = 4.0 * lanes
    obs[0, 0] = 1.0
    obs[0, 1] = 0.0
    obs[0, 2] = min(max(ey / y_half, -1.0), 1.0)
    obs[0, 3] = min(max(f[0, 3] * c0 / (2 * 40.0), -1.0), 1.0)
    obs[0, 4] = min(max(f[0, 3] * math.sin(eh) / (2 * 40.0), -1.0), 1.0)
    ego_lane = int(round(ey / 4.0))
    mid = (lanes - 1) / 2.0
    obs[0, 5] = (ego_lane - mid) / mid if mid > 0 else 0.0
    col = 6
    for s in range(3):
        if mask[s]:
            obs[0, col] = 1.0
            col += 1
    order = np.empty(n, np.int64)
    dists = np.empty(n)
    k = 0
    for j in range(1, n):
        if present[j, FUSED]:
            order[k] = j
            dists[k] = math.hypot(pos[j, FUSED, 0], pos[j, FUSED, 1])
            k += 1
    idx = np.argsort(dists[:k], kind="mergesort")
    for r in range(min(k, m - 1)):
        j = order[idx[r]]
        obs[r + 1, 0] = 1.0
        obs[r + 1, 1] = min(max(pos[j, FUSED, 0] / (5 * 40.0), -1.0), 1.0)
        obs[r + 1, 2] = min(max(pos[j, FUSED, 1] / y_half, -1.0), 1.0)
        obs[r + 1, 3] = min(max(vel[j, FUSED, 0] / (2 * 40.0), -1.0), 1.0)
        obs[r + 1, 4] = min(max(vel[j, FUSED, 1] / (2 * 40.0), -1.0), 1.0)
        wy = ey + s0 * pos[j, FUSED, 0] + c0 * pos[j, FUSED, 1]  # the object's lateral position on the road
        obs[r + 1, 5] = min(max((round(wy / 4.0) - ego_lane) / 2.0, -1.0), 1.0)
        col = 6
        for s in range(3):
            if mask[s]:
                obs[r + 1, col] = 1.0 if present[j, s] else 0.0
                col += 1


@njit(cache=True, nogil=True)
def _lane_rows(n, f, present, pos, vel, lanes, obs):
    """The ``"lanes"`` observation: ego row, then per lane (left, own, right) the nearest fused object ahead and
    behind along the road, from the same fused list as the ``"list"`` layout (see the module docstring)."""
    for r in range(obs.shape[0]):
        for c in range(obs.shape[1]):
            obs[r, c] = 0.0
    ey, eh, speed = f[0, 1], f[0, 2], f[0, 3]
    c0, s0 = math.cos(eh), math.sin(eh)
    ego_lane = min(max(int(round(ey / 4.0)), 0), lanes - 1)
    mid = (lanes - 1) / 2.0
    obs[0, 0] = 1.0
    obs[0, 1] = min(max((ey - 4.0 * ego_lane) / 2.0, -1.0), 1.0)
    obs[0, 2] = min(max(speed / MAX_SPEED, -1.0), 1.0)
    obs[0, 3] = (ego_lane - mid) / mid if mid > 0 else 0.0
    for d in range(3):
        lane = ego_lane + d - 1
        if lane < 0 or lane >= lanes:
            continue
        row = d + 1
        obs[row, 0] = 1.0
        best_a, best_b = LANE_AHEAD, LANE_BEHIND
        for j in range(1, n):
            if not present[j, FUSED]:
                continue
            px, py = pos[j, FUSED, 0], pos[j, FUSED, 1]
            along = c0 * px - s0 * py  # along the road
            if int(round((ey + s0 * px + c0 * py) / 4.0)) != lane:
                continue
            dv = c0 * vel[j, FUSED, 0] - s0 * vel[j, FUSED, 1]  # its speed along the road relative to the ego's
            if along > 0.0 and along < best_a:
                best_a = along
                obs[row, 1] = 1.0 - along / LANE_AHEAD
                obs[row, 2] = min(max(dv / MAX_SPEED, -1.0), 1.0)
            elif along <= 0.0 and -along < best_b:
                best_b = -along
                obs[row, 3] = 1.0 - (-along) / LANE_BEHIND
                obs[row, 4] = min(max(dv / MAX_SPEED, -1.0), 1.0)


@njit(cache=True, nogil=True, parallel=True)
def perceive_worlds(active, floats, counts, classes, colors, heights, keys, ticks, alphas, beta_ratios, tables_i, tables_r,
                    suns, shades, sky_luma, grid, gx0, gy0, res, surf_luma, elev, az_cos, az_sin, lidar_range, lidar_h,
                    drop, cam, rad, mask, rules, dt, lanes, present, pos, vel, prev_present, prev_pos, prev_vel,
                    obs, fterms, frows, fframes, fbeta, weights, ramp, weights5, ramp5):  # fmt: skip
    """Detect and fuse in every active world (parallel over worlds); see the module docstring. World ``w`` with
    ``frows[w] > 0`` is fogged by the field ``fterms[w, :frows[w]]`` laid at ``fframes[w]`` (peak extinction
    ``fbeta[w]``; ``weights`` … ``ramp5``: :func:`fog_gym.fog.lidar_field.field_pulse_weights` at the field step and
    at the coarse step), the others by their homogeneous level."""
    for w in prange(floats.shape[0]):
        if not active[w]:
            continue
        f = floats[w]
        n = counts[w]
        bx, by, byaw = f[:n, 0].copy(), f[:n, 1].copy(), f[:n, 2].copy()
        bl, bw = f[:n, 7].copy(), f[:n, 8].copy()
        bh = heights[w, :n].copy()
        vx = f[:n, 3] * np.cos(byaw)
        vy = f[:n, 3] * np.sin(byaw)
        key = keys[w]
        tick = ticks[w]
        terms = fterms[w, :frows[w]]
        lid_count = np.zeros(n)
        lid_cen = np.zeros((n, 3))
        if mask[LID]:
            PK.lidar_detect(n, bx, by, byaw, bl, bw, bh, bx[0], by[0], byaw[0], lidar_h, elev, az_cos, az_sin, lidar_range,
                            key, tick, alphas[w], beta_ratios[w], tables_i[w], tables_r[w], drop[0], drop[1], drop[2],
                            int(rules[4]), lid_count, lid_cen, terms, fframes[w], weights, ramp, weights5, ramp5,
                            fbeta[w], rules[5] > 0.5)  # fmt: skip
        cam_pix = np.zeros(n)
        cam_con = np.zeros(n)
        cam_bear = np.zeros(n)
        cam_size = np.zeros(n)
        if mask[CAM]:
            PK.camera_detect(n, bx, by, byaw, bl, bw, bh, colors[w, :n], bx[0], by[0], byaw[0], cam[0], cam[1],
                             cam[2], int(cam[3]), int(cam[4]), alphas[w], suns[w], shades[w, 0], shades[w, 1],
                             shades[w, 2], sky_luma, grid, gx0, gy0, res, surf_luma, int(rules[4]), cam[5], cam_pix,
                             cam_con, cam_bear, cam_size, terms, fframes[w])  # fmt: skip
        rad_hits = np.zeros(n)
        rad_rng = np.zeros(n)
        rad_az = np.zeros(n)
        rad_vr = np.zeros(n)
        if mask[RAD]:
            PK.radar_detect(n, bx, by, byaw, bl, bw, bh, vx, vy, bx[0], by[0], byaw[0], vx[0], vy[0], rad[0], rad[1],
                            rad[2], rad[3], rad[4], int(rad[5]), key, tick, rad_hits, rad_rng, rad_az, rad_vr)  # fmt: skip
        _fuse_world(n, f, classes[w], present[w], pos[w], vel[w], prev_present[w], prev_pos[w], prev_vel[w], lid_count,
                    lid_cen,
                    cam_pix, cam_con, cam_bear, cam_size, rad_hits, rad_rng, rad_az, rad_vr, mask, int(rules[0]),
                    rules[1], rules[2], cam[2], cam[0], rad[0], lidar_h, key, tick, dt, lanes, int(rules[3]), obs[w])  # fmt: skip
