"""Dataset generation: a plan of scenes (per-town budgets, exact day/night balance), one function per scene
(run by worker processes or as Ray tasks), and resume after a crash.

Generation sits on top of the env, the fog wrapper and the dataset format layer (:mod:`fog_gym.dataset`, which
imports neither); checking a set is :func:`fog_gym.dataset.validate.validate`.

A scene is fully determined by (base seed, scene index): its town, time of day, run number, env seed and folder
name all derive from them, so any scene can be regenerated bit for bit and a resumed run redoes exactly the
scenes that were not complete.

Example:
    >>> plan = plan_scenes(4, towns=("highway", "merge"), seed=0)
    >>> [(p.town, p.time_of_day, p.run) for p in plan]
    [('highway', 'day', 1), ('highway', 'night', 1), ('merge', 'day', 1), ('merge', 'night', 1)]
"""

from __future__ import annotations

import contextlib
import json
import shutil
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.world.towns import TOWNS
from fog_gym.fog import FOG_PRESETS
from fog_gym.fog.physics import FogField
from fog_gym.dataset.layout import DATA_ROOT, MODALITIES, SAMPLE_PERIOD_US, modality_channels, scene_folder_name, scene_id
from fog_gym.channels.spec import lidar_channel
from fog_gym.dataset.lock import LOCK_FILE, DatasetLock
from fog_gym.dataset.manifest import (
    FOG_FIELD_KINDS, MANIFEST_FILE, differences, make_manifest, read_manifest, write_manifest,
)  # fmt: skip
from fog_gym.dataset.writer import SceneWriter, WriteError, _atomic_write, build_index
from fog_gym.checks import option

PROGRESS_DIR = ".generate"  # completion markers, outside data_root so the layout stays exactly D2


@dataclass(frozen=True)
class SceneSpec:
    """Everything that defines one scene of a generated dataset."""

    index: int
    town: str
    time_of_day: str
    run: int
    seed: int
    resolution: tuple[int, int]
    seconds: float
    base_seed: int = 0
    modality: str = "full"  # a key of MODALITIES: "full" (35 channels), "lidar" or "cameras"
    fog_fields: str = "levels"  # one of FOG_FIELD_KINDS: how the three fog levels are laid out (scene_fog)
    cameras: tuple[str, ...] = ()  # write only these cameras' channels (empty: every camera of the modality)
    lidar_returns: str = "strongest"  # the LiDAR's return mode (fog_gym.fog.returns); others rename its channels
    lidar_motion: str = "instant"  # the LiDAR's sweep timing (fog_gym.sensors.motion); continuous renames them too
    camera_noise: str | None = None  # a camera noise preset (fog_gym.sensors.camera_noise), None: noise-free

    @property
    def own_lidar(self) -> bool:
        """Whether the LiDAR's channels are its own (another return mode or sweep timing), not FogDrive's."""
        return self.lidar_returns != "strongest" or self.lidar_motion != "instant"

    @property
    def channels(self) -> tuple[str, ...]:
        names = modality_channels(self.modality, tuple(self.cameras))
        if not self.own_lidar:
            return names
        lidar = lidar_channel("LIDAR_TOP", self.lidar_returns, self.lidar_motion)
        return tuple(n.replace("LIDAR_TOP", lidar, 1) if n.startswith("LIDAR_TOP") else n for n in names)

    @property
    def folder(self) -> str:
        number = TOWNS.index(self.town) + 1
        return scene_folder_name(number, self.time_of_day, self.run, scene_id(number, self.time_of_day, self.run, self.seed))

    @property
    def expected_samples(self) -> int:
        return int(round(self.seconds * 1e6 / SAMPLE_PERIOD_US)) + 1  # the reset frame plus one per keyframe


def plan_scenes(n_scenes: int, towns: tuple[str, ...] = TOWNS, seed: int = 0, resolution: tuple[int, int] = (1280, 960),
                seconds: float = 20.0, modality: str = "full", fog_fields: str = "levels",
                cameras: tuple[str, ...] = (), lidar_returns: str = "strongest", lidar_motion: str = "instant",
                camera_noise: str | None = None) -> list[SceneSpec]:  # fmt: skip
    """``n_scenes`` (even) spread over ``towns`` in day/night pairs, as evenly as possible, in a fixed order.

    ``modality`` "lidar" writes only :data:`~fog_gym.dataset.layout.MODALITIES` ``["lidar"]``: the same scenes,
    LiDAR files and boxes as "full" (cameras are still rendered, at ``resolution``, because a 3D box is kept only
    for a vehicle in some camera's view), without the 24 PNGs per sample that dominate the cost.

    ``modality`` "cameras" writes only the cameras' RGB, fog variants, depth and 2D boxes (and the 3D boxes);
    ``cameras`` (names, e.g. ``("CAM_FRONT", "CAM_LEFT")``) keeps only those cameras' channels of either set.
    ``lidar_returns`` "last" or "dual" records a LiDAR of that return mode (:mod:`fog_gym.fog.returns`): its
    channels are ``LIDAR_TOP_LAST`` / ``LIDAR_TOP_DUAL`` and their fog variants; ``lidar_motion`` "continuous" a sweep
    that takes time (:mod:`fog_gym.sensors.motion`; channels ``…_MOTION`` with a time column); ``camera_noise`` a
    preset of :data:`fog_gym.sensors.camera_noise.NOISE_PRESETS` records every camera with sensor noise.

    ``fog_fields`` lays each scene's three fog levels out in space (:func:`scene_fog`): ``levels`` (FogDrive's
    homogeneous fog), ``banks``, ``height`` or ``mixed``.
    """
    if fog_fields not in FOG_FIELD_KINDS:
        raise ValueError(f"fog_fields must be one of {FOG_FIELD_KINDS}, got {fog_fields!r}")
    modality_channels(modality, tuple(cameras))  # a bad modality or camera name is a ValueError naming it
    from fog_gym.fog.returns import check_mode

    check_mode(lidar_returns)
    lidar_channel("LIDAR_TOP", lidar_returns, lidar_motion)  # a bad motion is a ValueError naming it
    if camera_noise is not None:
        from fog_gym.sensors.camera_noise import NOISE_PRESETS

        if camera_noise not in NOISE_PRESETS:
            raise ValueError(f"camera_noise must be None or one of {sorted(NOISE_PRESETS)}, got {camera_noise!r}")
    if isinstance(n_scenes, bool) or not isinstance(n_scenes, int) or n_scenes < 2 or n_scenes % 2:
        raise ValueError(f"scenes must be an even number >= 2 (day/night pairs), got {n_scenes!r}")
    for t in towns:
        if t not in TOWNS:
            raise ValueError(f"town must be one of {TOWNS}, got {t!r}")
    if not towns:
        raise ValueError("towns must name at least one town")
    pairs = n_scenes // 2
    budget = [pairs // len(towns) + (k < pairs % len(towns)) for k in range(len(towns))]
    plan: list[SceneSpec] = []
    for town, n_pairs in zip(towns, budget):
        for run in range(1, n_pairs + 1):
            for tod in ("day", "night"):
                index = len(plan)
                scene_seed = int(np.random.SeedSequence([seed, index]).generate_state(1)[0] & 0x7FFFFFFF)
                plan.append(SceneSpec(index, town, tod, run, scene_seed, tuple(resolution), float(seconds), seed,
                                      modality, fog_fields, tuple(cameras), lidar_returns, lidar_motion,
                                      camera_noise))  # fmt: skip
    return plan


def scene_fog(spec: SceneSpec) -> list[FogField]:
    """The three fog levels of a scene (named light, moderate, dense, at FogDrive's visibilities), laid out as
    ``spec.fog_fields`` asks; the layout is drawn from (base seed, scene index), so a scene regenerates bit for bit,
    and is shared by the three levels (the pairing: only the density differs).

    * ``levels``: homogeneous fog (FogDrive's).
    * ``banks``: a :class:`~fog_gym.fog.fields.FogBank` of the level's visibility in clear air, its near face
      0–300 m ahead of the LiDAR at reset, 50–300 m long, edges 5–40 m wide, drifting at −3 … 3 m/s.
    * ``height``: :class:`~fog_gym.fog.fields.HeightFog`, the level's visibility at road level, thinning by ``e``
      every 3–30 m of height.
    * ``mixed``: per scene, one of homogeneous, bank, ground fog, or a bank over ground fog four times thinner.

    >>> spec = plan_scenes(2, towns=("highway",), fog_fields="banks")[0]
    >>> [(f.name, f.visibility, f.start == scene_fog(spec)[2].start) for f in scene_fog(spec)]
    [('light', 160.0, True), ('moderate', 100.0, True), ('dense', 50.0, True)]
    """
    from fog_gym.fog.fields import FogBank, FogSum, HeightFog, Homogeneous

    rng = np.random.default_rng(np.random.SeedSequence([spec.base_seed, spec.index, 0xF06]))
    bank = {"start": rng.uniform(0.0, 300.0), "length": rng.uniform(50.0, 300.0), "edge": rng.uniform(5.0, 40.0),
            "velocity": rng.uniform(-3.0, 3.0)}  # fmt: skip
    scale_height = rng.uniform(3.0, 30.0)
    kind = spec.fog_fields if spec.fog_fields != "mixed" else ("levels", "banks", "height", "both")[rng.integers(4)]
    out: list[FogField] = []
    for name, visibility in FOG_PRESETS.items():
        if kind == "levels":
            out.append(Homogeneous(visibility, name=name))
        elif kind == "banks":
            out.append(FogBank(visibility, name=name, **bank))
        elif kind == "height":
            out.append(HeightFog(visibility, scale_height, name=name))
        else:
            out.append(FogSum((HeightFog(4.0 * visibility, scale_height), FogBank(visibility, **bank)), name=name))
    return out


def generate_scene(root: str | Path, spec: SceneSpec | dict[str, Any]) -> str:
    """Render and write one scene (clean + three paired fog levels, laid out by :func:`scene_fog`); returns its
    folder name. A scene with fog fields writes each sample's fields beside it (:mod:`fog_gym.dataset.fog_record`).

    The ego drives with highway-env's IDLE meta-action (keep lane and speed); an episode that ends early
    (collision) gives a shorter scene.
    """
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.wrappers.fog import FogWrapper

    spec = spec if isinstance(spec, SceneSpec) else SceneSpec(**{**spec, "resolution": tuple(spec["resolution"]),
                                                                 "cameras": tuple(spec.get("cameras", ()))})  # fmt: skip
    root = Path(root)
    folder_path = root / DATA_ROOT / spec.folder
    if folder_path.exists():
        shutil.rmtree(folder_path)  # a partial scene from an interrupted run: redo it from its seed
    # the cameras are rendered in both modalities: FogDrive's 3D boxes are the vehicles annotated in some camera,
    # so a LiDAR-only scene gets exactly the boxes (and LiDAR files) of the full scene; only the writing is skipped
    env = FogWrapper(FogDriveEnv(town=spec.town, time_of_day=spec.time_of_day, resolution=spec.resolution,
                                 episode_seconds=spec.seconds, lidar_returns=spec.lidar_returns,
                                 lidar_motion=spec.lidar_motion, camera_noise=spec.camera_noise), scene_fog(spec))  # fmt: skip
    if not spec.own_lidar:
        writer = SceneWriter(root, spec.folder, spec.channels)
    else:  # the LiDAR's own channels: the rig's layout of them
        from fog_gym.sensors import rig_layout

        layout = rig_layout(env.unwrapped.config.rig)
        writer = SceneWriter(root, spec.folder, {c: layout[c] for c in spec.channels})
    fields = spec.fog_fields != "levels"  # a set of fog fields records every scene's, homogeneous ones included
    try:
        obs, info = env.reset(seed=spec.seed)
        writer.write_extrinsics(info["extrinsics"])
        writer.write_sample(0, obs, info, env.unwrapped.ego_pose_record(), env.field_record(fields))
        idle = env.unwrapped.idle_action
        index, done = 1, False
        while not done:
            obs, _, terminated, truncated, info = env.step(idle)
            writer.write_sample(index, obs, info, env.unwrapped.ego_pose_record(), env.field_record(fields))
            index += 1
            done = terminated or truncated
        writer.close()
        try:
            marker = {k: v for k, v in asdict(spec).items()
                      if (k != "fog_fields" or v != "levels") and (k != "cameras" or v)
                      and (k != "lidar_returns" or v != "strongest") and (k != "lidar_motion" or v != "instant")
                      and (k != "camera_noise" or v is not None)}  # (as before these fields)
            _atomic_write(root / PROGRESS_DIR / f"{spec.folder}.json", json.dumps(marker).encode())
        except WriteError as e:
            raise e.with_what(f"cannot mark scene {spec.folder} done") from None
    except BaseException:
        writer.close()
        shutil.rmtree(folder_path, ignore_errors=True)  # an unfinished scene is redone from its seed: free its space
        raise
    finally:
        env.close()
    return spec.folder


def pending_scenes(root: Path, plan: list[SceneSpec]) -> list[SceneSpec]:
    """Scenes of the plan that are not completely on disk."""
    return [s for s in plan if not (root / PROGRESS_DIR / f"{s.folder}.json").exists()]


def plan_manifest(plan: list[SceneSpec]) -> dict[str, Any]:
    """The manifest of a plan: scene count, resolution, seconds, base seed, towns in plan order."""
    if not plan:
        raise ValueError("the plan has no scenes")
    towns = list(dict.fromkeys(s.town for s in plan))
    first = plan[0]
    return make_manifest(len(plan), first.resolution, first.seconds, first.base_seed, towns, fog_levels=FOG_PRESETS,
                         channels=first.channels, fog_fields=first.fog_fields, camera_noise=first.camera_noise)  # fmt: skip


def check_manifest(root: Path, manifest: dict[str, Any], resume: bool) -> None:
    """Write the manifest of a new run; on resume, refuse settings that differ from the stored one."""
    stored = read_manifest(root)
    if stored is not None:
        diff = differences(stored, manifest)
        if diff:
            raise ValueError(f"{option('resume')} with settings that differ from the dataset's manifest "
                             f"({MANIFEST_FILE}): {'; '.join(diff)}")
        return
    started = any(p.is_dir() for p in (root / DATA_ROOT).iterdir()) if (root / DATA_ROOT).is_dir() else False
    if resume and started:
        raise ValueError(f"{root} has scenes but no {MANIFEST_FILE}: its settings cannot be checked, so it cannot "
                         "be resumed safely")
    write_manifest(root, manifest)


def check_root(root: Path, resume: bool) -> None:
    """Clear errors before any rendering: unwritable root, or a non-empty one without ``resume``."""
    if root.exists() and not root.is_dir():
        raise ValueError(f"dataset root {root} exists and is not a folder")
    if root.exists() and any(p.name != LOCK_FILE for p in root.iterdir()) and not resume:
        raise ValueError(f"dataset root {root} is not empty; pass {option('resume')} to continue an interrupted run")
    probe = root / ".write_probe"
    try:
        (root / DATA_ROOT).mkdir(parents=True, exist_ok=True)
        probe.write_text("ok")
        probe.unlink()
    except OSError as e:
        with contextlib.suppress(OSError):
            probe.unlink()
        raise ValueError(f"dataset root {root} is not writable: {e}") from None


def generate(root: str | Path, plan: list[SceneSpec], workers: int = 1, resume: bool = False,
             ray_address: str | None = None, progress: bool = True) -> dict[str, Any]:  # fmt: skip
    """Generate the plan's pending scenes in parallel, then rebuild the index; returns the index tables.

    The run's settings go to ``index/manifest.json`` before any rendering; ``resume`` with settings that differ
    from the manifest is a ``ValueError`` naming them. A file that cannot be written (disk full, permission lost)
    raises :class:`~fog_gym.dataset.writer.WriteError` once every worker has stopped and removed its unfinished
    scene and temporary files; with the cause removed, ``resume=True`` completes the set byte for byte as an
    uninterrupted run. Each sample's ego pose goes beside it (:mod:`fog_gym.dataset.poses`). The run holds the root's
    lock (:class:`~fog_gym.dataset.lock.DatasetLock`): a second writer meanwhile gets
    :class:`~fog_gym.dataset.lock.DatasetLocked`, and a lock left by a killed run is taken over.
    """

    root = Path(root)
    if root.exists() and not root.is_dir():
        raise ValueError(f"dataset root {root} exists and is not a folder")
    with DatasetLock(root, "generate"):  # one writer per root; with Ray the driver holds it
        return _generate_locked(root, plan, workers, resume, ray_address, progress)


def _generate_locked(root: Path, plan: list[SceneSpec], workers: int, resume: bool, ray_address: str | None,
                     progress: bool) -> dict[str, Any]:  # fmt: skip
    from tqdm import tqdm

    check_root(root, resume)
    check_manifest(root, plan_manifest(plan), resume)
    todo = pending_scenes(root, plan)
    bar = tqdm(total=len(plan), initial=len(plan) - len(todo), desc="scenes", unit="scene", disable=not progress)
    if ray_address is not None:
        try:
            import ray
        except ImportError:
            raise SystemExit("--ray needs the optional 'ray' extra: pip install -e '.[ray]'") from None
        ray.init(address=ray_address)
        task = ray.remote(generate_scene)
        refs = [task.remote(str(root), asdict(s)) for s in todo]
        while refs:
            done, refs = ray.wait(refs)
            ray.get(done)
            bar.update(len(done))
    elif workers <= 1:
        try:
            for s in todo:
                generate_scene(root, s)
                bar.update()
        finally:
            bar.close()
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as pool:
            futures = [pool.submit(generate_scene, str(root), s) for s in todo]
            try:
                for fut in as_completed(futures):
                    fut.result()
                    bar.update()
            except BaseException:
                for f in futures:  # no new scenes; the running ones end (each cleans up its files) before we leave
                    f.cancel()
                raise
            finally:
                bar.close()
    bar.close()
    return build_index(root)
