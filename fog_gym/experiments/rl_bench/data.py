"""What the RL benchmark's agents train and are tested on: the training conditions and their fog schedules, the
environments, the vector-env factory and the policy that fits an observation space.

Conditions: clear, light, moderate, dense (fixed fog), mixed (a seeded level per episode), curriculum (clear →
160 → 100 → 50 m in steps), success (advance when 80 % of the last 10 episodes were crash-free) and continuous
(visibility sliding from clear to 50 m linearly in α). The curricula are spread over the run's expected episodes
(:data:`EPISODE_STEPS`) and applied by :class:`fog_gym.rl.sb3.VecFogCurriculum`.

The vector env is made by one function looked up by name in :data:`VEC_ENVS`: :func:`subproc_vec_env` (SB3's
``SubprocVecEnv``) or :func:`native_vec_env` (fog-gym's native vector env behind its SB3 adapter).

Example:
    >>> fog, schedule = schedule_for("curriculum", 0, 50_000, "FogDriveRLHazard-v0", 20.0)
    >>> fog, schedule.episodes_per_level
    ('clear', 333)
    >>> schedule_for("moderate", 0, 2048, "FogDriveRL-v0", 20.0)
    ('moderate', None)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

CONDITIONS = ("clear", "light", "moderate", "dense", "mixed", "curriculum", "success", "continuous")
#: The default study's conditions (``moderate`` is there on request: ``--conditions``).
DEFAULT_CONDITIONS = ("clear", "light", "dense", "mixed", "curriculum", "success", "continuous")
TEST_LEVELS = ("clear", "light", "moderate", "dense")
#: highway-env's DiscreteMetaAction, the RL presets' actions.
LANE_LEFT, IDLE, LANE_RIGHT, FASTER, SLOWER = range(5)
#: Evaluation episodes run on seeds 10⁶ + k, disjoint from training's.
EVAL_SEED = 1_000_000
#: FogDrive's RL presets act at 5 Hz.
POLICY_HZ = 5.0
#: Mean training-episode length [policy steps] of each task, to spread the schedules over a run: FogDriveRL-v0's
#: agents rarely crash (100 steps per 20 s); FogDriveRLHazard-v0's crash often (25–37 steps measured over the first
#: seed's 5×10⁴-step runs of every fixed condition). Other tasks: the episode length at 5 Hz.
EPISODE_STEPS = {"FogDriveRL-v0": 100, "FogDriveRLHazard-v0": 30}


def schedule_for(condition: str, seed: int, steps: int, env_id: str, episode_seconds: float,
                 episode_steps: int | None = None):  # fmt: skip
    """``(initial fog, schedule or None)`` of a training condition. The step curriculum reaches dense fog after
    60 % of the run's expected episodes, the continuous one after 80 %; the expected episodes are ``steps`` over the
    mean training-episode length ``episode_steps`` (default: the task's, :data:`EPISODE_STEPS`)."""
    from fog_gym.fog.schedules import ContinuousSchedule, MixedSampler, StepSchedule, SuccessSchedule

    full = max(1, round(episode_seconds * POLICY_HZ))
    length = min(episode_steps or EPISODE_STEPS.get(env_id, full), full)
    episodes = max(4, steps // length)
    if condition in ("clear", "light", "moderate", "dense"):
        return condition, None
    return {
        "mixed": ("clear", MixedSampler(seed=seed)),
        "curriculum": ("clear", StepSchedule(episodes_per_level=max(1, episodes // 5))),
        "success": ("clear", SuccessSchedule()),
        "continuous": ("clear", ContinuousSchedule(episodes=max(1, episodes * 4 // 5))),
    }[condition]  # fmt: skip


def env_fn(env_id: str, fog: Any, seed: int, kwargs: Mapping[str, Any]) -> Callable[[], Any]:
    """A function that makes one env (``gym.make(env_id, fog=fog, **kwargs)``) and resets it with ``seed``; it
    imports fog_gym itself, so it works in a fresh worker process."""

    def make():
        import gymnasium as gym

        import fog_gym  # noqa: F401  (registers the env in the worker)

        env = gym.make(env_id, fog=fog, **kwargs)
        env.reset(seed=seed)
        return env

    return make


def subproc_vec_env(env_id: str, n: int, fog: Any, seed: int, kwargs: Mapping[str, Any]):
    """``n`` envs in subprocesses (one in-process env for ``n = 1``), seeded ``seed + rank``: an SB3 ``VecEnv``."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    cls = SubprocVecEnv if n > 1 else DummyVecEnv
    return cls([env_fn(env_id, fog, seed + r, kwargs) for r in range(n)])


def native_vec_env(env_id: str, n: int, fog: Any, seed: int, kwargs: Mapping[str, Any]):
    """fog-gym's native vector env (``n`` worlds in this process, :mod:`fog_gym.envs.vector`) behind the SB3 adapter;
    sub-env i of the first reset is seeded ``seed + i``."""
    import gymnasium as gym

    import fog_gym  # noqa: F401
    from fog_gym.rl.sb3 import VectorEnvAdapter

    venv = VectorEnvAdapter(gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", fog=fog,
                                         info_detections=False, **kwargs))  # fmt: skip
    venv.seed(seed)
    return venv


#: Vector-env factories by name: ``(env_id, n, fog, seed, kwargs) -> SB3 VecEnv``.
VEC_ENVS: dict[str, Callable[..., Any]] = {"subproc": subproc_vec_env, "native": native_vec_env}
#: Sensor sets of the perceived-objects observation (``--sensor-sets``): name → the env's ``sensors``.
SENSOR_SETS: dict[str, list[str]] = {"camera": ["camera"], "lidar": ["lidar"], "radar": ["radar"],
                                     "fused": ["camera", "lidar", "radar"]}  # fmt: skip


def agent_name(condition: str, seed: int, sensors: str | None = None) -> str:
    """An agent's name: ``<condition>_s<seed>``, or ``<sensors>_<condition>_s<seed>`` in a study over sensor sets."""
    return f"{sensors}_{condition}_s{seed}" if sensors else f"{condition}_s{seed}"


def vec_env(kind: str, env_id: str, n: int, fog: Any, seed: int, kwargs: Mapping[str, Any]):
    """The vector env of factory ``kind`` (:data:`VEC_ENVS`)."""
    if kind not in VEC_ENVS:
        raise ValueError(f"vec_env must be one of {sorted(VEC_ENVS)}, got {kind!r}")
    return VEC_ENVS[kind](env_id, n, fog, seed, kwargs)


def policy_for(space: Any) -> str:
    """The SB3 policy for an observation space: ``MultiInputPolicy`` for a Dict, ``MlpPolicy`` for a Box.

    >>> import gymnasium as gym, numpy as np
    >>> policy_for(gym.spaces.Dict({"a": gym.spaces.Box(0, 1, (2,))})), policy_for(gym.spaces.Box(0, 1, (4,)))
    ('MultiInputPolicy', 'MlpPolicy')
    """
    from gymnasium import spaces

    if isinstance(space, spaces.Dict):
        return "MultiInputPolicy"
    if isinstance(space, spaces.Box):
        return "MlpPolicy"
    raise ValueError(f"no policy for observation space {space!r}: give one (policy=...)")
