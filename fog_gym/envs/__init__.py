"""The environments, registered in one place (as Gymnasium's ``envs/__init__.py``): ``import fog_gym`` runs this.

========================  =================================================================================
``FogDrive-v0``           the FogDrive rig on a highway-env town (:class:`~fog_gym.envs.fogdrive.FogDriveEnv`),
                          ``fog=`` wraps it in :class:`~fog_gym.wrappers.FogWrapper`
``FogDriveRL-v0``         the RL preset: 64×64 front camera and LiDAR bird's-eye image, 5 Hz policy
``FogDriveRLHazard-v0``   the RL preset on stalled vehicles ahead: seeing far enough decides the episode
``FogDriveRLObjects-v0``  the hazard task on perceived objects, lanes layout, a flat vector (CleanRL, SB3)
``FogDriveRLFogBank-v0``  the hazard task with a fog bank on the road ahead, drawn per episode (pixels)
========================  =================================================================================

Entry points live in :mod:`fog_gym.envs.presets`, the env class in :mod:`fog_gym.envs.fogdrive`, its configuration
in :mod:`fog_gym.envs.config`; the RL presets' perceived-objects observation in :mod:`fog_gym.envs.objects` and
their native vector env (``gym.make_vec(id, num_envs, vectorization_mode="vector_entry_point")``) in
:mod:`fog_gym.envs.vector`, sharded over worker processes with ``shards=K`` (:mod:`fog_gym.envs.sharded`); the vector
entry points are here.

Example:
    >>> import gymnasium as gym
    >>> sorted(k for k in gym.registry if k.startswith("FogDrive"))
    ['FogDrive-v0', 'FogDriveRL-v0', 'FogDriveRLFogBank-v0', 'FogDriveRLHazard-v0', 'FogDriveRLObjects-v0']
"""

from __future__ import annotations

from typing import Any

from gymnasium.envs.registration import register

#: Every registered id → (its entry point, its native vector entry point or None).
ENV_IDS = {
    "FogDrive-v0": ("fog_gym.envs.presets:make_fogdrive", None),
    "FogDriveRL-v0": ("fog_gym.envs.presets:make_fogdrive_rl", "fog_gym.envs:make_rl_vector"),
    "FogDriveRLHazard-v0": ("fog_gym.envs.presets:make_fogdrive_rl_hazard", "fog_gym.envs:make_rl_hazard_vector"),
    "FogDriveRLObjects-v0": ("fog_gym.envs.presets:make_fogdrive_rl_objects", "fog_gym.envs:make_rl_objects_vector"),
    "FogDriveRLFogBank-v0": ("fog_gym.envs.presets:make_fogdrive_rl_fog_bank", "fog_gym.envs:make_rl_fog_bank_vector"),
}

for _id, (_entry, _vector) in ENV_IDS.items():
    register(id=_id, entry_point=_entry, vector_entry_point=_vector, max_episode_steps=None)


def make_vector(env_id: str, num_envs: int = 1, shards: int = 1, **kwargs: Any) -> Any:
    """The vector env of ``env_id``: :class:`~fog_gym.envs.vector.FogDriveVectorEnv` in this process (``shards=1``),
    or its worlds over ``shards`` worker processes (:class:`~fog_gym.envs.sharded.ShardedVectorEnv`)."""
    kwargs.pop("max_episode_steps", None)
    if shards == 1 and not isinstance(shards, (bool, float)):  # any other value: ShardedVectorEnv checks it
        from fog_gym.envs.vector import FogDriveVectorEnv

        return FogDriveVectorEnv(env_id, num_envs, **kwargs)
    from fog_gym.envs.sharded import ShardedVectorEnv

    return ShardedVectorEnv(env_id, num_envs, shards, **kwargs)


def make_rl_vector(num_envs: int = 1, shards: int = 1, **kwargs: Any) -> Any:
    """``FogDriveRL-v0``'s vector entry point (``shards``: worker processes, see :func:`make_vector`)."""
    return make_vector("FogDriveRL-v0", num_envs, shards, **kwargs)


def make_rl_objects_vector(num_envs: int = 1, shards: int = 1, **kwargs: Any) -> Any:
    """``FogDriveRLObjects-v0``'s vector entry point (``shards``: worker processes, see :func:`make_vector`)."""
    return make_vector("FogDriveRLObjects-v0", num_envs, shards, **kwargs)


def make_rl_hazard_vector(num_envs: int = 1, shards: int = 1, **kwargs: Any) -> Any:
    """``FogDriveRLHazard-v0``'s vector entry point (``shards``: worker processes, see :func:`make_vector`)."""
    return make_vector("FogDriveRLHazard-v0", num_envs, shards, **kwargs)


def make_rl_fog_bank_vector(num_envs: int = 1, shards: int = 1, **kwargs: Any) -> Any:
    """``FogDriveRLFogBank-v0``'s vector entry point (``shards``: worker processes, see :func:`make_vector`)."""
    return make_vector("FogDriveRLFogBank-v0", num_envs, shards, **kwargs)
