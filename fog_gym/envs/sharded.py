"""The RL presets' vector env sharded over processes: ``gym.make_vec(id, num_envs=N, vectorization_mode=
"vector_entry_point", shards=K)``.

:class:`ShardedVectorEnv` runs K worker processes, each with its own :class:`~fog_gym.envs.vector.FogDriveVectorEnv`
of about N/K worlds (shard k holds sub-envs ``[start_k, start_k + n_k)``), steps them at once and concatenates their
results, so the worlds' Python and kernels use K cores. Every worker's numba kernels get ``cores // K`` threads, and
its worlds render on ``threads`` threads (:class:`~fog_gym.envs.vector.FogDriveVectorEnv`'s; default: ``cores // K``,
at most its default); ``context`` picks the multiprocessing start method (``"fork"``, ``"spawn"``, ``"forkserver"``;
default: the platform's).

It is the same vector env as ``shards=1`` sub-env for sub-env: ``reset(seed=s)`` gives sub-env i the episode of a
single env reset with ``seed=s + i``; autoresets (``NEXT_STEP``, ``SAME_STEP``, ``DISABLED``), ``reset_mask`` and infos
follow Gymnasium's ``SyncVectorEnv`` (per-key arrays with ``_key`` masks); ``get_attr`` / ``set_attr`` / ``call`` reach
every sub-env's attributes and methods (values and results must pickle), ``set_fog`` and ``reset_one`` the sub-env they
name (so :class:`~fog_gym.rl.sb3.VectorEnvAdapter` and :class:`~fog_gym.wrappers.VectorFogCurriculum` work unchanged). Bad arguments fail in the main process before a
worker starts; a worker's error is raised again in the main process.

Example:
    >>> import gymnasium as gym, fog_gym
    >>> envs = gym.make_vec("FogDriveRLHazard-v0", num_envs=4, vectorization_mode="vector_entry_point",
    ...                     observation="objects", shards=2)
    >>> obs, infos = envs.reset(seed=0)
    >>> obs.shape, envs.shard_sizes
    ((4, 8, 9), (2, 2))
    >>> envs.close()
"""

from __future__ import annotations

import multiprocessing as mp
import os
import traceback
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from fog_gym.envs.vector import DEFAULT_THREADS, check_vector_arguments, sub_env_seeds, world_threads


def shard_sizes(num_envs: int, shards: int) -> tuple[int, ...]:
    """``num_envs`` worlds over ``shards`` processes, as evenly as possible (the first ones get the remainder).

    >>> shard_sizes(16, 2), shard_sizes(10, 4)
    ((8, 8), (3, 3, 2, 2))
    """
    return tuple(num_envs // shards + (k < num_envs % shards) for k in range(shards))


def _worker(conn: Any, env_id: str, size: int, threads: int, world_threads: int, autoreset_mode: str,
            info_detections: bool, kwargs: dict) -> None:  # fmt: skip
    try:
        import numba

        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
        from fog_gym.envs.vector import FogDriveVectorEnv

        envs = FogDriveVectorEnv(env_id, size, autoreset_mode=autoreset_mode, info_detections=info_detections,
                                 threads=min(world_threads, size), **kwargs)  # fmt: skip
        conn.send(("ok", (envs.single_observation_space, envs.single_action_space)))
    except Exception as e:  # noqa: BLE001 - sent to the main process, which raises it
        conn.send(("error", (e, traceback.format_exc())))
        conn.close()
        return
    while True:
        try:
            cmd, args = conn.recv()
        except (EOFError, KeyboardInterrupt):
            break
        if cmd == "close":
            envs.close()
            conn.send(("ok", None))
            break
        try:
            if cmd == "mode":
                envs.metadata = {**envs.metadata, "autoreset_mode": AutoresetMode(args)}
                out = None
            else:  # reset, step, set_fog, set_attr, call, get_attr, reset_one
                out = getattr(envs, cmd)(*args[0], **args[1])
            conn.send(("ok", out))
        except Exception as e:  # noqa: BLE001
            conn.send(("error", (e, traceback.format_exc())))
    conn.close()


class ShardedVectorEnv(gym.vector.VectorEnv):
    """N worlds of an RL preset over ``shards`` worker processes (see the module docstring)."""

    def __init__(self, env_id: str, num_envs: int, shards: int, autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 info_detections: bool = True, context: str | None = None, threads: int | None = None,
                 **kwargs: Any) -> None:  # fmt: skip
        mode = check_vector_arguments(env_id, num_envs, autoreset_mode, kwargs)
        threads_arg = None if threads is None else world_threads(threads, 1)
        if isinstance(shards, bool) or not isinstance(shards, (int, np.integer)) or not 1 <= shards <= num_envs:
            raise ValueError(f"shards must be an integer from 1 to num_envs ({num_envs}), got {shards!r}")
        self.env_id, self.num_envs = env_id, int(num_envs)
        self.shard_sizes = shard_sizes(self.num_envs, int(shards))
        self._starts = np.concatenate([[0], np.cumsum(self.shard_sizes)])
        self.metadata = {"autoreset_mode": mode, "render_modes": []}
        self._mode = mode
        ctx = mp.get_context(context)
        threads = max(1, (os.cpu_count() or 1) // len(self.shard_sizes))
        per_shard = min(threads, DEFAULT_THREADS) if threads_arg is None else threads_arg
        self._conns, self._procs = [], []
        for size in self.shard_sizes:
            parent, child = ctx.Pipe()
            proc = ctx.Process(target=_worker, args=(child, env_id, size, threads, per_shard, mode.value,
                                                     info_detections, kwargs), daemon=True)  # fmt: skip
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)
        try:
            spaces = self._gather()
        except Exception:
            self.close_extras()  # the shards that did start stop again
            raise
        self.single_observation_space, self.single_action_space = spaces[0]
        self._obs: list | None = None  # each shard's latest observations (a masked reset keeps the others')
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)

    # -- Gymnasium VectorEnv API ----------------------------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        from fog_gym.envs.vector import reset_mask

        self._sync_mode()
        seeds = sub_env_seeds(seed, self.num_envs)
        options = dict(options) if options is not None else None
        mask = reset_mask(options, self.num_envs)
        if self._obs is None and not mask.all():
            raise RuntimeError("the first reset resets every sub-env (no reset_mask)")
        asked = []
        for k, conn in enumerate(self._conns):
            a, b = self._starts[k], self._starts[k + 1]
            if mask[a:b].any():  # a shard none of whose sub-envs reset is not asked
                opts = {**(options or {}), "reset_mask": mask[a:b].copy()}
                conn.send(("reset", ((), {"seed": seeds[a:b], "options": opts})))
                asked.append(k)
        answers = dict(zip(asked, self._gather(asked)))
        self._obs = [answers[k][0] if k in answers else self._obs[k] for k in range(len(self._conns))]
        infos = [answers[k][1] if k in answers else {} for k in range(len(self._conns))]
        return self._concat(self._obs), merge_infos(infos, self.shard_sizes)

    def step(self, actions: Any):
        self._sync_mode()
        actions = np.asarray(actions).reshape(self.num_envs)
        for k, conn in enumerate(self._conns):
            conn.send(("step", ((actions[self._starts[k]:self._starts[k + 1]],), {})))
        parts = self._gather()
        self._obs = [p[0] for p in parts]
        obs = self._concat(self._obs)
        rewards, terminated, truncated = (np.concatenate([p[i] for p in parts]) for i in (1, 2, 3))
        return obs, rewards, terminated, truncated, merge_infos([p[4] for p in parts], self.shard_sizes)

    # -- sub-env access (curricula, SB3) ---------------------------------------------------------------
    def set_fog(self, index: int, fog: Any) -> None:
        """Sub-env ``index``'s fog from its next reset on."""
        k, i = self._locate(index)
        self._ask(k, "set_fog", i, fog)

    def reset_one(self, index: int, seed: int | None = None) -> tuple[Any, dict]:
        """Reset sub-env ``index`` alone (an SB3 curriculum's re-reset)."""
        self._sync_mode()
        k, i = self._locate(index)
        return self._ask(k, "reset_one", i, seed)

    def set_attr(self, name: str, values: Any) -> None:
        """Set ``name`` on every sub-env: one value for all, or a list of ``num_envs`` values (as ``SyncVectorEnv``)."""
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"values must be a list of num_envs={self.num_envs} values, got {len(values)}")
        for k, conn in enumerate(self._conns):
            conn.send(("set_attr", ((name, list(values[self._starts[k]:self._starts[k + 1]])), {})))
        self._gather()

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple:
        """Call each sub-env's method ``name`` with the same arguments (as ``SyncVectorEnv``; results cross the
        process boundary, so they must pickle)."""
        for conn in self._conns:
            conn.send(("call", ((name, *args), kwargs)))
        return tuple(v for part in self._gather() for v in part)

    def get_attr(self, name: str) -> tuple:
        """Each sub-env's attribute ``name`` (it must pickle)."""
        for conn in self._conns:
            conn.send(("get_attr", ((name,), {})))
        return tuple(v for part in self._gather() for v in part)

    def close_extras(self, **kwargs: Any) -> None:
        for conn, proc in zip(self._conns, self._procs):
            try:
                if proc.is_alive():
                    conn.send(("close", None))
                    conn.recv()
            except (BrokenPipeError, EOFError, OSError):
                pass
            proc.join(timeout=10)
            if proc.is_alive():
                proc.terminate()
            conn.close()

    # -- helpers --------------------------------------------------------------------------------------
    def _locate(self, index: int) -> tuple[int, int]:
        if not 0 <= int(index) < self.num_envs:
            raise IndexError(f"sub-env index must lie in [0, {self.num_envs}), got {index!r}")
        k = int(np.searchsorted(self._starts, int(index), side="right")) - 1
        return k, int(index) - int(self._starts[k])

    def _ask(self, k: int, cmd: str, *args: Any) -> Any:
        self._conns[k].send((cmd, (args, {})))
        return self._receive(k)

    def _receive(self, k: int) -> Any:
        try:
            status, out = self._conns[k].recv()
        except EOFError as e:
            raise RuntimeError(f"shard {k}'s worker process ended unexpectedly") from e
        if status == "error":
            error, trace = out
            raise error from RuntimeError(f"in shard {k}'s worker process:\n{trace}")
        return out

    def _gather(self, shards: Sequence[int] | None = None) -> list:
        outs, first_error = [], None
        for k in range(len(self._conns)) if shards is None else shards:  # every answer is read: none left in a pipe
            try:
                outs.append(self._receive(k))
            except Exception as e:  # noqa: BLE001
                first_error = first_error or e
        if first_error is not None:
            raise first_error
        return outs

    def _sync_mode(self) -> None:
        """Pass a changed ``metadata["autoreset_mode"]`` (SB3's adapter switches it to SAME_STEP) on to the workers."""
        mode = AutoresetMode(self.metadata["autoreset_mode"])
        if mode != self._mode:
            for conn in self._conns:
                conn.send(("mode", mode.value))
            self._gather()
            self._mode = mode

    def _concat(self, parts: list) -> Any:
        if isinstance(parts[0], dict):
            return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
        return np.concatenate(parts)


def _blank(sample: np.ndarray, n: int, key: str) -> np.ndarray:
    """The value of an info key for ``n`` sub-envs that did not report it: False masks, None objects, zeros."""
    if key.startswith("_"):
        return np.zeros(n, bool)
    if sample.dtype == object:
        return np.full(n, None, dtype=object)
    return np.zeros((n, *sample.shape[1:]), sample.dtype)


def merge_infos(parts: list[dict], sizes: Sequence[int]) -> dict:
    """Gymnasium vector infos of consecutive shards (``sizes`` sub-envs each) as the infos of one vector env: every
    array concatenated, a key some shard lacks filled for its sub-envs (masks False, objects None, numbers 0), nested
    dicts merged alike.

    >>> a = {"speed": np.array([1.0, 2.0]), "_speed": np.array([True, True])}
    >>> merged = merge_infos([a, {}], [2, 1])
    >>> merged["speed"].tolist(), merged["_speed"].tolist()
    ([1.0, 2.0, 0.0], [True, True, False])
    """
    out: dict = {}
    for key in dict.fromkeys(k for p in parts for k in p):
        values = [p.get(key) for p in parts]
        sample = next(v for v in values if v is not None)
        if isinstance(sample, dict):
            out[key] = merge_infos([v if v is not None else {} for v in values], sizes)
        else:
            sample = np.asarray(sample)
            out[key] = np.concatenate([np.asarray(v) if v is not None else _blank(sample, n, key)
                                       for v, n in zip(values, sizes)])  # fmt: skip
    return out
