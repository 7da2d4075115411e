"""The entry point of every registered environment (:mod:`fog_gym.envs` registers them):

* ``FogDrive-v0`` — :func:`make_fogdrive`: the full FogDrive rig (:class:`~fog_gym.envs.fogdrive.FogDriveEnv`),
  wrapped in :class:`~fog_gym.wrappers.FogWrapper` when ``fog`` is given;
* ``FogDriveRL-v0`` — :func:`make_fogdrive_rl`: highway town with 20 vehicles on 3 lanes, 20 Hz simulation and a
  5 Hz policy (100 steps per 20 s episode), one 64×64 front camera rendered at that size, a 32-channel LiDAR turned
  into a 64×64 bird's-eye image, in-place fog (``fog=``, default clear; ``set_fog`` between episodes), no ground
  truth. Observation: ``{"CAM_FRONT": (3, 64, 64) uint8, "LIDAR_BEV": (2, 64, 64) uint8}`` — SB3's
  ``MultiInputPolicy`` takes it;
* ``FogDriveRLHazard-v0`` — :func:`make_fogdrive_rl_hazard`: the same sensors on a task where seeing far enough
  decides the episode (stalled vehicles ahead);
* ``FogDriveRLFogBank-v0`` — :func:`make_fogdrive_rl_fog_bank`: the hazard task with a fog bank on the road ahead,
  drawn per episode.

The env class never imports the wrappers; the presets compose them.

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
import numpy as np

from fog_gym.envs.fogdrive import FogDriveEnv
from fog_gym.sensors.camera import FOGDRIVE_CAMERA_POSES, CameraConfig
from fog_gym.sensors.lidar import LidarConfig
from fog_gym.sensors.rig import RigConfig
from fog_gym.world.hazards import HazardConfig


def make_fogdrive(fog: Any = None, airlight: Any = "estimate", **kwargs: Any) -> gym.Env:
    """Entry point of ``FogDrive-v0``: :class:`FogDriveEnv`, wrapped in :class:`fog_gym.wrappers.FogWrapper` when
    ``fog`` is given ("clear", "light", "moderate", "dense", metres, or a list for paired mode).

    >>> env = make_fogdrive(fog="light", town="merge", resolution=(16, 12), cameras=["CAM_FRONT"])
    >>> type(env).__name__, env.unwrapped.config.town
    ('FogWrapper', 'merge')
    """
    if fog is None:
        return FogDriveEnv(**kwargs)
    from fog_gym.wrappers.fog import FogWrapper, parse_fog_levels  # lazily: the wrappers package loads on demand

    parse_fog_levels(fog)  # bad fog fails before the world is built
    return FogWrapper(FogDriveEnv(**kwargs), fog, airlight=airlight)


RL_TRAFFIC = {"vehicles_count": 20, "lanes_count": 3}


#: Values of the RL presets' ``observation`` argument.
OBSERVATIONS: tuple[str, ...] = ("pixels", "objects")
#: The RL presets' arguments of the perceived-objects observation (:class:`~fog_gym.perception.objects.ObjectsConfig`).
OBJECT_ARGS: tuple[str, ...] = ("sensors", "max_objects", "min_points", "min_pixels", "min_contrast", "layout", "flat")


def objects_config(kwargs: dict[str, Any]) -> Any:
    """Pop the perceived-objects arguments from ``kwargs`` into an :class:`~fog_gym.perception.objects.ObjectsConfig`
    (bad values fail here, naming the argument)."""
    from fog_gym.perception.objects import ObjectsConfig

    return ObjectsConfig(**{k: kwargs.pop(k) for k in OBJECT_ARGS if k in kwargs})


def check_observation(observation: Any) -> str:
    if not isinstance(observation, str) or observation not in OBSERVATIONS:
        raise ValueError(f"observation must be one of {OBSERVATIONS}, got {observation!r}")
    return observation


def make_fogdrive_rl(fog: Any = "clear", town: str = "highway", camera_size: Sequence[int] = (64, 64),
                     grayscale: bool = False, bev_size: int = 64, frame_stack: int = 1,
                     highway_config: dict | None = None, render_mode: str | None = None, bev_ahead: float = 0.0,
                     observation: str = "pixels", **kwargs: Any) -> gym.Env:  # fmt: skip
    """Build the RL preset (see the module docstring); ``bev_ahead`` shifts the bird's-eye image forward (metres,
    :class:`~fog_gym.wrappers.LidarBEV`'s ``ahead``); ``kwargs`` go to :class:`fog_gym.envs.fogdrive.FogDriveEnv`.

    ``observation="objects"`` gives the perceived-objects observation instead (:mod:`fog_gym.envs.objects`;
    ``sensors``, ``max_objects``, ``min_points``, ``min_pixels``, ``min_contrast``, ``layout`` configure it; highway town only)."""
    from fog_gym.wrappers import FogWrapper, LidarBEV, ResizeCameras, SelectKeys, StackFrames

    check_observation(observation)
    if observation == "objects":
        from fog_gym.envs.objects import FogDriveObjectsEnv

        objects = objects_config(kwargs)
        hazards = kwargs.pop("hazards", None)
        episode_seconds = kwargs.pop("episode_seconds", 20.0)
        info_detections = kwargs.pop("info_detections", True)
        banks = kwargs.pop("banks", None)
        kwargs.pop("traffic", None)
        if kwargs:
            raise ValueError(f"observation='objects' does not take {sorted(kwargs)}")
        if town != "highway":
            raise ValueError(f"observation='objects' runs on the highway town only, got town {town!r}")
        return FogDriveObjectsEnv({**RL_TRAFFIC, **(highway_config or {})}, hazards, fog, objects, episode_seconds,
                                  info_detections, banks=banks)  # fmt: skip
    if "info_detections" in kwargs:
        raise ValueError("info_detections configures observation='objects'; this env has observation='pixels'")
    leftover = [k for k in OBJECT_ARGS if k in kwargs]
    if leftover:
        raise ValueError(f"{leftover} configure observation='objects'; this env has observation='pixels'")

    w, h = (int(v) for v in camera_size)
    rig = RigConfig((
        ("CAM_FRONT", CameraConfig("CAM_FRONT", FOGDRIVE_CAMERA_POSES["CAM_FRONT"], w, h, 100.0)),
        ("LIDAR_TOP", LidarConfig.fogdrive(channels=32, points_per_second=200_000.0)),
    ))
    kwargs.setdefault("traffic", "native" if town == "highway" else "fast")
    kwargs.setdefault("static_world", "town")
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
      (:class:`~fog_gym.world.hazards.HazardConfig`: the first 60–120 m ahead, then every 70–140 m, each in a random
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
    hz = HazardConfig() if hazards is None else hazards
    return make_fogdrive_rl(fog=fog, highway_config={**HAZARD_TRAFFIC, **(highway_config or {})}, hazards=hz,
                            bev_ahead=kwargs.pop("bev_ahead", HAZARD_BEV_AHEAD), **kwargs)  # fmt: skip


#: FogDriveRLObjects-v0's observation arguments: the layout the RL study learns on, as one flat vector.
OBJECTS_PRESET = {"observation": "objects", "layout": "lanes", "flat": True}


def make_fogdrive_rl_objects(fog: Any = "clear", **kwargs: Any) -> gym.Env:
    """``FogDriveRLObjects-v0``: the hazard task (:func:`make_fogdrive_rl_hazard`) on perceived objects in the
    ``"lanes"`` layout (per lane the nearest fused object ahead and behind) as a flat ``Box(-1, 1, (20,))``, the
    observation on which the RL study's agents learn; SB3's ``MlpPolicy`` and CleanRL's PPO take it as it is.

    >>> import gymnasium as gym, fog_gym
    >>> env = gym.make("FogDriveRLObjects-v0", fog="dense")
    >>> env.observation_space.shape, int(env.action_space.n)
    ((20,), 5)
    """
    return make_fogdrive_rl_hazard(fog=fog, **{**OBJECTS_PRESET, **kwargs})


def check_banks(banks: Any, kwargs: dict[str, Any]) -> tuple[Any, Any]:
    """``FogDriveRLFogBank-v0``'s bank settings (a :class:`~fog_gym.fog.banks.BankConfig`, default when None) and
    the bank its env is built with (every reset replaces it); a ``fog`` among ``kwargs`` or another ``banks`` is a
    ValueError before any world is built."""
    from fog_gym.fog.banks import BankConfig

    if "fog" in kwargs:
        raise ValueError("FogDriveRLFogBank-v0 draws a fog bank per episode: configure it with banks=BankConfig(...), "
                         "not fog=")  # fmt: skip
    banks = BankConfig() if banks is None else banks
    if not isinstance(banks, BankConfig):
        raise ValueError(f"banks must be a fog_gym.fog.banks.BankConfig, got {banks!r}")
    return banks, banks.draw(np.random.default_rng(0))


def make_fogdrive_rl_fog_bank(banks: Any = None, observation: str = "pixels", **kwargs: Any) -> gym.Env:
    """``FogDriveRLFogBank-v0``: the hazard task (:func:`make_fogdrive_rl_hazard`: stalled vehicles ahead, the ego at
    25 m/s) with a fog bank on the road ahead, drawn anew at every reset
    (:class:`~fog_gym.wrappers.FogBankEpisodes`, ``banks`` a :class:`~fog_gym.fog.banks.BankConfig`): its near face
    140–340 m ahead (beyond every sensor's clear-air reach at reset), 100–400 m deep, 25–80 m of visibility inside,
    edges 5–30 m wide, clear air around it. Stalled vehicles are placed as in the hazard task, so some lie inside
    the bank. The question the preset asks: does the agent slow down before the wall of fog, not inside it?

    ``observation="objects"`` gives the perceived objects (:mod:`fog_gym.envs.objects`), fogged by the same bank
    (drawn from the same seed).

    >>> import gymnasium as gym, fog_gym
    >>> env = gym.make("FogDriveRLFogBank-v0")
    >>> obs, info = env.reset(seed=0)
    >>> info["fog"]["type"], sorted(obs)
    ('FogBank', ['CAM_FRONT', 'LIDAR_BEV'])
    """
    from fog_gym.wrappers import FogBankEpisodes

    banks, first = check_banks(banks, kwargs)
    if check_observation(observation) == "objects":  # the worlds draw the bank themselves (as the vector env's do)
        return make_fogdrive_rl_hazard(fog=first, observation="objects", banks=banks, **kwargs)
    return FogBankEpisodes(make_fogdrive_rl_hazard(fog=first, **kwargs), banks)
