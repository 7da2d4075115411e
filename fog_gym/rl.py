"""The RL preset ``FogDriveRL-v0`` and an SB3 callback for fog curricula.

``FogDriveRL-v0``: highway town with 20 vehicles on 3 lanes, 20 Hz simulation and a 5 Hz policy (100 steps per
20 s episode), one 64×64 front camera rendered at that size, a 32-channel LiDAR turned into a 64×64 bird's-eye
image, in-place fog (``fog=``, default clear; ``set_fog`` between episodes), no ground truth. Observation:
``{"CAM_FRONT": (3, 64, 64) uint8, "LIDAR_BEV": (2, 64, 64) uint8}`` — SB3's ``MultiInputPolicy`` takes it.

Example:
    >>> import gymnasium as gym, fog_gym
    >>> env = gym.make("FogDriveRL-v0", fog="dense")
    >>> sorted((k, s.shape) for k, s in env.observation_space.spaces.items())
    [('CAM_FRONT', (3, 64, 64)), ('LIDAR_BEV', (2, 64, 64))]
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym

from fog_gym.config import FOGDRIVE_CAMERA_POSES, CameraConfig, RigConfig
from fog_gym.curriculum import FogSchedule
from fog_gym.lidar import LidarConfig

RL_TRAFFIC = {"vehicles_count": 20, "lanes_count": 3}


def make_fogdrive_rl(fog: Any = "clear", town: str = "highway", camera_size: Sequence[int] = (64, 64),
                     grayscale: bool = False, bev_size: int = 64, frame_stack: int = 1,
                     highway_config: dict | None = None, render_mode: str | None = None, bev_ahead: float = 0.0,
                     **kwargs: Any) -> gym.Env:  # fmt: skip
    """Build the RL preset (see the module docstring); ``bev_ahead`` shifts the bird's-eye image forward (metres,
    :class:`~fog_gym.wrappers.LidarBEV`'s ``ahead``); ``kwargs`` go to :class:`fog_gym.env.FogDriveEnv`."""
    from fog_gym.env import FogDriveEnv
    from fog_gym.wrappers import FogWrapper, LidarBEV, ResizeCameras, SelectKeys, StackFrames

    w, h = (int(v) for v in camera_size)
    rig = RigConfig((
        ("CAM_FRONT", CameraConfig("CAM_FRONT", FOGDRIVE_CAMERA_POSES["CAM_FRONT"], w, h, 100.0)),
        ("LIDAR_TOP", LidarConfig.fogdrive(channels=32, points_per_second=200_000.0)),
    ))
    base = FogDriveEnv(town=town, rig=rig, keyframe_frequency=5, highway_config={**RL_TRAFFIC, **(highway_config or {})},
                       labels=None, render_mode=render_mode, **kwargs)  # fmt: skip
    env: gym.Env = FogWrapper(base, fog)
    env = LidarBEV(env, size=bev_size, metres=64.0, ahead=bev_ahead)
    env = ResizeCameras(env, size=(w, h), grayscale=grayscale)
    env = SelectKeys(env, ["CAM_FRONT", "LIDAR_BEV"])
    if frame_stack > 1:
        env = StackFrames(env, frame_stack)
    return env


#: FogDriveRLHazard-v0's traffic, actions and reward (highway-env config keys).
HAZARD_TRAFFIC = {
    "vehicles_count": 10, "lanes_count": 3,
    "action": {"type": "DiscreteMetaAction", "target_speeds": [0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0]},
    "reward_speed_range": [0.0, 30.0], "high_speed_reward": 1.0, "collision_reward": -1.0,
    "right_lane_reward": 0.0, "lane_change_reward": 0.0, "normalize_reward": False,
}  # fmt: skip
#: FogDriveRLHazard-v0's bird's-eye image: 64 m square from 8 m behind the LiDAR to 56 m ahead of it.
HAZARD_BEV_AHEAD = 24.0


def make_fogdrive_rl_hazard(fog: Any = "clear", hazards: Any = None, highway_config: dict | None = None,
                            **kwargs: Any) -> gym.Env:  # fmt: skip
    """``FogDriveRLHazard-v0``: FogDriveRL-v0's sensors on a task where seeing far enough decides the episode.

    - **World**: the highway town, 3 lanes, 10 IDM vehicles, and stalled vehicles ahead of the ego
      (:class:`~fog_gym.config.HazardConfig`: the first 60–120 m ahead, then every 70–140 m, each in a random
      lane, over the whole episode).
    - **Observation**: as FogDriveRL-v0 (64×64 front camera, 64×64 LiDAR bird's-eye image), but the bird's-eye
      image looks ahead: it spans 8 m behind to 56 m ahead of the LiDAR (1 m per pixel, ±32 m across).
    - **Actions**: highway-env's ``DiscreteMetaAction`` (lane left, idle, lane right, faster, slower) with target
      speeds 0, 5, …, 30 m/s; the ego starts at 25 m/s.
    - **Reward** per step: forward speed / 30 m/s (0–1), −1 on a collision; no normalisation, no lane term.
    - **Termination**: a collision (with a stalled or a moving vehicle); truncation after 20 s (100 steps at
      5 Hz). A lane change off the road's edge does nothing (highway-env's meta-actions).

    So a blind agent must crawl (or crash), and one that sees a stalled vehicle in time can change lanes at speed:
    how far the sensors see through the fog sets what the agent can earn. ``hazards`` (a ``HazardConfig``) and
    ``highway_config`` override the preset's; ``kwargs`` go to :func:`make_fogdrive_rl`.

    >>> import gymnasium as gym, fog_gym
    >>> env = gym.make("FogDriveRLHazard-v0", fog="dense")
    >>> int(env.action_space.n), sorted(env.observation_space.spaces)
    (5, ['CAM_FRONT', 'LIDAR_BEV'])
    """
    from fog_gym.config import HazardConfig

    hz = HazardConfig() if hazards is None else hazards
    return make_fogdrive_rl(fog=fog, highway_config={**HAZARD_TRAFFIC, **(highway_config or {})}, hazards=hz,
                            bev_ahead=kwargs.pop("bev_ahead", HAZARD_BEV_AHEAD), **kwargs)  # fmt: skip


def curriculum_callback(schedule: FogSchedule, verbose: int = 0):
    """An SB3 callback that drives ``schedule`` over the training run's episodes (all sub-envs together).

    At every finished episode it counts the episode, reports success (no crash) to the schedule, and calls
    ``env_method("set_fog", level, indices=[i])`` for that sub-env (``SubprocVecEnv`` included). SB3 vector envs
    reset a sub-env inside ``step``, before callbacks run, so the level takes effect from that sub-env's *next*
    episode boundary. For the level at the very next episode use :class:`fog_gym.sb3.VecFogCurriculum` (one
    schedule over all sub-envs) or the ``FogCurriculum`` wrapper inside each env (one schedule per env). The
    visibility in force is logged as ``fog/visibility_m``.
    """
    from stable_baselines3.common.callbacks import BaseCallback

    class FogCurriculumCallback(BaseCallback):
        def __init__(self) -> None:
            super().__init__(verbose)
            self.schedule = schedule
            self.episodes = 0

        def _on_training_start(self) -> None:
            level = self.schedule.level(0)
            self.training_env.env_method("set_fog", level)

        def _on_step(self) -> bool:
            for i, (done, info) in enumerate(zip(self.locals["dones"], self.locals["infos"])):
                if not done:
                    continue
                self.episodes += 1
                self.schedule.record(not info.get("crashed", False))
                level = self.schedule.level(self.episodes)
                self.training_env.env_method("set_fog", level, indices=[i])
                vis = float("inf") if level == "clear" else float(level) if not isinstance(level, str) else None
                if vis is None:
                    from fog_gym.fog import parse_fog

                    vis = parse_fog(level).visibility_m
                self.logger.record("fog/visibility_m", min(vis, 1e4))
                self.logger.record("fog/episodes", self.episodes)
            return True

    return FogCurriculumCallback()
