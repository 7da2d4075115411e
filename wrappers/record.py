"""``RecordFogDrive``: write every episode of a FogDrive-v0 env as a FogDrive scene on disk."""

from __future__ import annotations

import copy
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from fog_gym.dataset.lock import DatasetLock
from fog_gym.dataset.layout import CAMERAS, DATA_ROOT, parse_scene_folder, scene_folder_name, scene_id
from fog_gym.dataset.writer import SceneWriter, WriteError, build_index
from fog_gym.fog.physics import parse_fog
from fog_gym.wrappers.fog import FogWrapper

PAIRED_LEVELS = ["light", "moderate", "dense"]


class RecordFogDrive(gym.Wrapper):
    """Records each episode — clean data and the three fog levels paired from one render, depth, semantics,
    point clouds and boxes — as ``data_root/data_collection_T<town>_<tod>_run<i>_<id>/`` under ``root``, and
    rebuilds ``index/{scene,sample,sample_data}.json`` from disk when an episode ends and on ``close``.

    Wrap a clean FogDrive-v0 env (the paired fog wrapper is added) or one already in paired fog with the three
    FogDrive levels — or with three fog fields named light, moderate and dense (``FogBank(50.0, 120.0, 80.0,
    name="dense")``, …), whose parameters, frame and time then go beside each sample
    (:mod:`fog_gym.dataset.fog_record`). The rig must hold the FogDrive rig (4 cameras, LiDAR, semantic LiDAR, radar) with ground
    truth on; every further sensor of the rig (a rear radar, a second LiDAR, another camera with its fog levels,
    depth, semantics and 2D boxes) is recorded too, each channel in the folder its sensor declares, and the
    layout goes with the set (``index/channels.json``) for ``validate`` and the loaders. Runs are numbered after those already under ``root`` for the same town and time of day.

    Writing overlaps simulation: sample k is encoded and written (its files in parallel by ``workers``
    threads, default one per core, ``BBOX_3D`` last) while the env simulates sample k + 1; ``step`` waits for
    sample k before handing sample k + 1 over, so at most one sample is in flight. The index is rebuilt, and
    ``close`` returns, only after every write has finished; a failed write is raised at the next call, as a
    :class:`~fog_gym.dataset.writer.WriteError` (``str()``: ``<what> (<path>): <reason>``) with no temporary file
    left behind: the samples written before it stay complete and indexed. Each sample's ego pose goes beside it
    (``ego_pose/``, :mod:`fog_gym.dataset.poses`).

    The wrapper holds the root's lock (:class:`~fog_gym.dataset.lock.DatasetLock`) from construction to ``close``:
    a second writer of the root meanwhile (another recorder, ``generate``, ``export``) gets
    :class:`~fog_gym.dataset.lock.DatasetLocked` naming this process.

    >>> import tempfile, fog_gym
    >>> env = RecordFogDrive(fog_gym.FogDriveEnv(resolution=(32, 24), episode_seconds=0.2), tempfile.mkdtemp())
    >>> _ = env.reset(seed=0); _ = env.step(1); _ = env.step(1)
    >>> env.close(); len(fog_gym.dataset.FogDrive(env.root).sample)
    3
    """

    def __init__(self, env: gym.Env, root: str | Path, workers: int | None = None) -> None:
        base = env.unwrapped
        rig = getattr(base, "config", None) and base.config.rig
        if rig is None:
            raise ValueError("RecordFogDrive wraps a FogDrive-v0 environment")
        missing = [c for c in CAMERAS if c not in base.camera_names]
        missing += [n for n in ("lidar", "semantic_lidar", "radar") if getattr(rig, n) is None]
        if missing or base.config.labels is None:
            raise ValueError(f"RecordFogDrive needs the full FogDrive rig with ground truth; missing: {missing or ['labels']}")
        fog = _find_fog(env)
        if fog is None:
            env = FogWrapper(env, PAIRED_LEVELS)
        elif not fog.paired or not _fogdrive_levels(fog):
            raise ValueError("RecordFogDrive needs clean data plus the paired levels light, moderate, dense: FogDrive's "
                             "homogeneous levels, or three fog fields named light, moderate and dense")  # fmt: skip
        self.root = Path(root)
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ValueError(f"workers must be a positive integer or None, got {workers!r}")
        # one writer per dataset root: held until close (DatasetLocked names the holder of a root in use)
        self._lock = DatasetLock(self.root, "RecordFogDrive").acquire()
        try:
            (self.root / DATA_ROOT).mkdir(parents=True, exist_ok=True)
        except OSError as e:
            self._lock.release()
            raise ValueError(f"cannot write the dataset root {self.root}: {e}") from None
        super().__init__(env)
        self._fog = _find_fog(env)
        self.workers = workers
        from fog_gym.sensors import rig_layout

        #: The layout written, from the rig: every sensor's channels in rig order (a channel without data in the
        #: observation, such as the fog variants of a sensor kind without a fog model, is left out), then BBOX_3D.
        obs_keys = self.env.observation_space.spaces
        self.layout = {ch: spec for ch, spec in rig_layout(rig).items()
                       if spec.encoding in ("box2d", "box3d") or ch in obs_keys}  # fmt: skip
        self.channels = tuple(self.layout)
        self._writer: SceneWriter | None = None
        self._index = 0
        self._background: ThreadPoolExecutor | None = None
        self._pending: Future | None = None

    def _flush(self) -> None:
        """Wait for the sample in flight; re-raise its error."""
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def _submit(self, index: int, obs: dict[str, Any], info: dict[str, Any]) -> None:
        self._flush()
        assert self._writer is not None
        frozen_obs = {k: np.array(v, copy=True) for k, v in obs.items()}  # the env may reuse its buffers
        frozen_info = {k: copy.deepcopy(info[k]) for k in ("boxes_2d", "boxes_3d")}
        ego_pose = self.env.unwrapped.ego_pose_record()  # now: the env moves on while the sample is written
        fog_field = self._fog.field_record()  # None for homogeneous fog
        if self._background is None:
            self._background = ThreadPoolExecutor(1, thread_name_prefix="fogdrive-record")
        self._pending = self._background.submit(self._writer.write_sample, index, frozen_obs, frozen_info, ego_pose,
                                                fog_field)  # fmt: skip

    def _next_run(self, town: int, tod: str) -> int:
        runs = [p[2] for p in (parse_scene_folder(d.name) for d in (self.root / DATA_ROOT).iterdir()) if p and p[:2] == (town, tod)]
        return max(runs, default=0) + 1

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if self._writer is not None:
            self._flush()
            self._writer.close()
            build_index(self.root)
        obs, info = self.env.reset(seed=seed, options=options)
        base = self.env.unwrapped
        town, tod = base.config.town_number, base.config.time_of_day
        run = self._next_run(town, tod)
        folder = scene_folder_name(town, tod, run, scene_id(town, tod, run, base.episode_seed))
        self._writer = SceneWriter(self.root, folder, self.layout, workers=self.workers)
        self._writer.write_extrinsics(info["extrinsics"])
        self._submit(0, obs, info)
        self._index = 1
        info["scene_folder"] = self._writer.folder
        return obs, info

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._writer is None:
            raise RuntimeError("call reset() before step()")
        self._submit(self._index, obs, info)
        self._index += 1
        if terminated or truncated:
            self._flush()
            build_index(self.root)
        return obs, reward, terminated, truncated, info

    def close(self) -> None:
        """Wait for the last sample, rebuild the index, close the env. A failed write (``WriteError``: disk full,
        permission lost) is raised after the index of the complete samples has been rebuilt, if it can be."""
        error: BaseException | None = None
        try:
            self._flush()
        except BaseException as e:
            error = e
        if self._background is not None:
            self._background.shutdown(wait=True)
            self._background = None
        if self._writer is not None:
            self._writer.close()
            self._writer = None
            try:
                build_index(self.root)
            except WriteError as e:
                error = error or e
        self._lock.release()
        super().close()
        if error is not None:
            raise error


def _fogdrive_levels(fog: FogWrapper) -> bool:
    """Whether a paired fog wrapper's levels are FogDrive's: the three presets, or fields with their names."""
    if [lv.name for lv in fog.levels] != PAIRED_LEVELS:
        return False
    return fog.fields or list(fog.levels) == [parse_fog(name) for name in PAIRED_LEVELS]


def _find_fog(env: gym.Env) -> FogWrapper | None:
    while isinstance(env, gym.Wrapper):
        if isinstance(env, FogWrapper):
            return env
        env = env.env
    return None
