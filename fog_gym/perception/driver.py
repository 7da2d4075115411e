"""What perception is worth: a scripted driver that uses only the perceived objects, and the sensors' reach.

:class:`DetectionDriver` reads the perceived-objects observation of ``FogDriveRLHazard-v0`` (nothing else): it
cruises at the highest target speed from which it can stop within its sensors' reach in the current fog
(``v = √(2·b·(reach − margin))``, b = 4 m/s², margin 10 m), and when an object ahead in its lane is slower than
itself (a stalled vehicle, or traffic it would close in on within 4 s) it changes to an adjacent lane that its
detections show free, else slows down. :func:`sensor_reach` measures the reach it is given: per sensor set and fog
level, the 95th percentile of the distances at which vehicles are detected. The driver's return and collision rate
per sensor set and fog level (:func:`drive`) bound what an agent on that observation can reach.

Example:
    >>> import gymnasium as gym, fog_gym
    >>> env = gym.make("FogDriveRLHazard-v0", observation="objects", sensors=("radar",))
    >>> obs, _ = env.reset(seed=0)
    >>> DetectionDriver(reach=100.0).act(obs) in range(5)
    True
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from fog_gym.world.traffic import kernels as K

LANE_LEFT, IDLE, LANE_RIGHT, FASTER, SLOWER = 0, 1, 2, 3, 4
#: The hazard preset's target speeds [m/s].
HAZARD_SPEEDS = np.arange(0.0, 31.0, 5.0)


class DetectionDriver:
    """A scripted policy over the perceived-objects observation (see the module docstring); ``reach`` is how far its
    sensors see in the current fog [m], ``lanes`` the road's lane count, ``speeds`` the target speeds."""

    def __init__(self, reach: float, lanes: int = 3, speeds: np.ndarray = HAZARD_SPEEDS, brake: float = 4.0,
                 margin: float = 10.0, y_range: float | None = None) -> None:  # fmt: skip
        if not (isinstance(reach, (int, float)) and math.isfinite(reach) and reach > 0):
            raise ValueError(f"reach must be a positive number of metres, got {reach!r}")
        self.reach = float(reach)
        self.lanes = int(lanes)
        self.speeds = np.asarray(speeds, float)
        v = math.sqrt(2 * brake * max(self.reach - margin, 0.0))
        ok = self.speeds[self.speeds <= v + 1e-9]
        self.cruise = float(ok.max()) if len(ok) else 0.0
        self.y_range = float(y_range) if y_range is not None else K.LANE_WIDTH * self.lanes

    def act(self, obs: np.ndarray) -> int:
        """The meta-action for one observation (rows: ego, then objects; features presence, x, y, vx, vy, …)."""
        ego = obs[0]
        evx, evy = float(ego[3]) * 80.0, float(ego[4]) * 80.0
        speed, heading = math.hypot(evx, evy), math.atan2(evy, evx)
        ego_y = float(ego[2]) * self.y_range
        lane = int(min(max(round(ego_y / K.LANE_WIDTH), 0), self.lanes - 1))
        rows = obs[1:][obs[1:, 0] > 0]
        xe, ye = rows[:, 1] * 200.0, rows[:, 2] * self.y_range  # ego frame
        c, s = math.cos(heading), math.sin(heading)
        x, y = xe * c - ye * s, xe * s + ye * c  # along and across the road
        vx = (rows[:, 3] * c - rows[:, 4] * s) * 80.0
        obj_lane = np.round((ego_y + y) / K.LANE_WIDTH).astype(int)

        def blocked(ln: int, ahead: float, behind: float) -> bool:
            return bool(np.any((obj_lane == ln) & (x > -behind) & (x < ahead)))

        changing = abs(ego_y - lane * K.LANE_WIDTH) > 0.6
        # threats ahead in my lane: slower than me and reached within 4 s or within my stopping distance
        mine = (obj_lane == lane) & (x > 0)
        closing = mine & (vx < -1.0) & ((x / np.maximum(-vx, 1e-6) < 4.0) | (x < speed * speed / 8.0 + 15.0))
        if closing.any():
            if not changing:
                for cand, action in ((lane - 1, LANE_LEFT), (lane + 1, LANE_RIGHT)):
                    if 0 <= cand < self.lanes and not blocked(cand, 40.0, 12.0):
                        return action
            return SLOWER
        if changing:
            return IDLE
        if speed < self.cruise - 2.5:
            return FASTER
        if speed > self.cruise + 2.5:
            return SLOWER
        return IDLE


def sensor_reach(sensors: tuple[str, ...], fog: Any, episodes: int = 8, seed: int = 3_000_000,
                 percentile: float = 95.0, env_id: str = "FogDriveRLHazard-v0", **kwargs: Any) -> float:  # fmt: skip
    """How far a sensor set sees in fog ``fog`` on the hazard preset: the ``percentile`` of the distances at which
    its fused list holds a vehicle, over ``episodes`` episodes driven at the ego's initial speed (``kwargs``: more
    arguments of the env)."""
    import gymnasium as gym

    env = gym.make(env_id, observation="objects", sensors=sensors, fog=fog, **kwargs)
    dists: list[float] = []
    for e in range(episodes):
        _, info = env.reset(seed=seed + e)
        done = False
        while not done:
            fused = info["detections"]["fused"]
            dists += fused["distance"][: fused["count"]].tolist()
            _, _, term, trunc, info = env.step(IDLE)
            done = term or trunc
    return float(np.percentile(dists, percentile)) if dists else 0.0


def drive(sensors: tuple[str, ...], fog: Any, reach: float, episodes: int = 32, seed: int = 2_000_000,
          env_id: str = "FogDriveRLHazard-v0", **kwargs: Any) -> dict[str, float]:  # fmt: skip
    """:class:`DetectionDriver` on the hazard preset: mean return, collision rate and mean speed over ``episodes``
    (seeds ``seed + k``; ``kwargs``: more arguments of the env)."""
    import gymnasium as gym

    env = gym.make(env_id, observation="objects", sensors=sensors, fog=fog, **kwargs)
    driver = DetectionDriver(reach)
    returns, crashes, speeds = [], [], []
    for e in range(episodes):
        obs, _ = env.reset(seed=seed + e)
        total, done, info = 0.0, False, {}
        while not done:
            obs, r, term, trunc, info = env.step(driver.act(obs))
            total += r
            speeds.append(info["speed"])
            done = term or trunc
        returns.append(total)
        crashes.append(float(info["crashed"]))
    return {"return": float(np.mean(returns)), "collisions": float(np.mean(crashes)), "speed": float(np.mean(speeds)),
            "reach": reach, "cruise": driver.cruise}  # fmt: skip
