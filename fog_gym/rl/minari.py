"""Record FogDrive episodes into a `Minari <https://minari.farama.org>`_ dataset (Farama's offline-RL format).

:func:`collect` runs a policy (``None``: uniformly random actions) in any FogDrive env — the RL preset
``FogDriveRL-v0`` by default in ``fog-gym minari`` — and stores observations (all keys of a ``Dict`` space, or the
ones named in ``keys``), actions, rewards, terminations and truncations exactly (``jpeg_encoding=False``: lossless),
with the fog level, town, time of day and fog-gym version in the dataset's metadata and each episode's seed and fog
visibility in its episode metadata. Minari's ``DataCollector`` needs jax (``minari[create]``, ≈ 600 MB); fog-gym
fills Minari's own ``EpisodeBuffer`` and calls ``minari.create_dataset_from_buffers`` instead, so the ``minari``
extra stays light (``minari[arrow]``).

Example (where the datasets go: ``MINARI_DATASETS_PATH``, default ``~/.minari/datasets``):
    >>> # ds = collect(gym.make("FogDriveRL-v0", fog="dense"), None, episodes=5, dataset_id="fog-gym/highway-dense-random-v0")
    >>> # minari.load_dataset("fog-gym/highway-dense-random-v0").total_episodes  →  5
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from fog_gym.checks import option

_DATASET_ID = re.compile(r"^(?:[A-Za-z0-9_.-]+/)*[A-Za-z0-9_.-]+-v\d+$")


def _require_minari():
    try:
        import minari
    except ImportError:  # pragma: no cover - depends on the install
        raise ImportError("Minari export needs the minari extra: pip install 'fog-gym[minari]'") from None
    return minari


def _policy_fn(policy: Any, action_space: gym.Space) -> Callable[[Any], Any]:
    if policy is None:
        return lambda obs: action_space.sample()
    if hasattr(policy, "predict"):  # a Stable-Baselines3 model
        return lambda obs: policy.predict(obs, deterministic=True)[0]
    if callable(policy):
        return policy
    raise TypeError(f"policy must be None, a callable obs → action or an SB3 model, got {type(policy).__name__}")


def _select_space(space: gym.Space, keys: Sequence[str] | None) -> gym.Space:
    if keys is None:
        return space
    if isinstance(keys, str) or not isinstance(space, gym.spaces.Dict):
        raise ValueError("keys must be a list of observation keys of a Dict observation space, "
                         f"got {keys!r} for {type(space).__name__}")  # fmt: skip
    missing = [k for k in keys if k not in space.spaces]
    if missing or not keys:
        raise ValueError(f"keys must be a non-empty list of {sorted(space.spaces)}, got {list(keys)!r}")
    return gym.spaces.Dict({k: space.spaces[k] for k in keys})


def _fog_name(info: dict) -> str:
    from fog_gym.fog import FogLevel

    fog = info.get("fog")
    if not isinstance(fog, dict) or "visibility_m" not in fog:
        return "clear"
    return FogLevel.from_visibility(float(fog["visibility_m"])).name


def collect(env: gym.Env, policy: Any = None, episodes: int = 1, dataset_id: str = "fog-gym/highway-random-v0",
            keys: Sequence[str] | None = None, seed: int = 0, algorithm_name: str | None = None,
            description: str | None = None, overwrite: bool = False, progress: bool = True) -> Any:  # fmt: skip
    """Run ``episodes`` episodes of ``env`` with ``policy`` and save them as Minari dataset ``dataset_id``.

    Episode ``i`` is reset with ``seed + i`` (random actions are drawn from the action space seeded by ``seed``),
    so a call is reproducible. Returns the ``minari.MinariDataset``. An existing ``dataset_id`` is an error unless
    ``overwrite``. Bad arguments fail before the first episode. A relative ``MINARI_DATASETS_PATH`` is made
    absolute (against the working folder) first: Minari 0.5 mishandles relative roots.
    """
    minari = _require_minari()
    from minari.data_collector import EpisodeBuffer
    from tqdm import tqdm

    import fog_gym

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be a positive integer, got {episodes!r}")
    if not isinstance(dataset_id, str) or not _DATASET_ID.match(dataset_id):
        raise ValueError(f"dataset_id must look like 'namespace/name-v0' (letters, digits, _ . -), got {dataset_id!r}")
    root = os.environ.get("MINARI_DATASETS_PATH")
    if root and not os.path.isabs(root):  # Minari 0.5 writes a relative root's episodes into a nested wrong path
        os.environ["MINARI_DATASETS_PATH"] = os.path.abspath(root)
    space = _select_space(env.observation_space, keys)
    act = _policy_fn(policy, env.action_space)
    if dataset_id in minari.list_local_datasets():
        if not overwrite:
            raise FileExistsError(f"Minari dataset {dataset_id!r} exists; pass {option('overwrite')} to replace it")
        minari.delete_dataset(dataset_id)
    pick = (lambda o: {k: o[k] for k in space.spaces}) if keys is not None else (lambda o: o)
    env.action_space.seed(seed)
    buffers, episode_meta = [], []
    for i in tqdm(range(episodes), desc=f"recording {dataset_id}", unit="episode", disable=not progress):
        obs, info = env.reset(seed=seed + i)
        observations, actions, rewards, terms, truncs = [pick(obs)], [], [], [], []
        fog = _fog_name(info)
        visibility = float(info.get("fog", {}).get("visibility_m", math.inf)) if isinstance(info.get("fog"), dict) else math.inf
        done = False
        while not done:
            action = act(obs)
            obs, reward, terminated, truncated, info = env.step(action)
            observations.append(pick(obs))
            actions.append(np.asarray(action))
            rewards.append(float(reward))
            terms.append(bool(terminated))
            truncs.append(bool(truncated))
            done = terminated or truncated
        if isinstance(space, gym.spaces.Dict):
            stacked: Any = {k: np.stack([o[k] for o in observations]) for k in space.spaces}
        else:
            stacked = np.stack(observations)
        buffers.append(EpisodeBuffer(id=i, seed=seed + i, observations=stacked, actions=np.stack(actions),
                                     rewards=rewards, terminations=terms, truncations=truncs))  # fmt: skip
        episode_meta.append({"seed": seed + i, "fog_level": fog,
                             "fog_visibility_m": visibility if math.isfinite(visibility) else "inf"})  # fmt: skip
    base = env.unwrapped
    config = getattr(base, "config", None)
    levels = sorted({m["fog_level"] for m in episode_meta})
    meta = {
        "fog_level": levels[0] if len(levels) == 1 else levels,
        "town": getattr(config, "town", "unknown"),
        "time_of_day": getattr(config, "time_of_day", "unknown"),
        "fog_gym_version": fog_gym.__version__,
        "observation_keys": sorted(space.spaces) if isinstance(space, gym.spaces.Dict) else [],
    }
    desc = description or (f"{episodes} episodes of {env.spec.id if env.spec else type(base).__name__} in "
                            f"{meta['town']} ({meta['time_of_day']}), fog {meta['fog_level']}, "
                            f"policy {algorithm_name or ('random' if policy is None else 'given')}")  # fmt: skip
    with warnings.catch_warnings():  # a bare FogDriveEnv has no registry spec; Minari warns about that, twice
        warnings.filterwarnings("ignore", message=".*(eval_env|env_spec)`? is (set to )?None", category=UserWarning)
        dataset = minari.create_dataset_from_buffers(
            dataset_id, buffers, env=env.spec, eval_env=env.spec, observation_space=space,
            action_space=env.action_space, algorithm_name=algorithm_name or ("random" if policy is None else "policy"),
            author="fog-gym", author_email="n/a", code_permalink="fog_gym.rl.minari.collect", description=desc,
            data_format="arrow", jpeg_encoding=False,
        )  # fmt: skip
    dataset.storage.update_metadata(meta)
    dataset.storage.update_episode_metadata(episode_meta)
    return minari.load_dataset(dataset_id)
