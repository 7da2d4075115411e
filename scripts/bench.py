#!/usr/bin/env python
"""Per-stage timing of FogDrive-v0 against bare highway-env. This script only reports numbers and never
asserts a timing.

The script prints Markdown tables to stdout. Progress bars go to stderr.

1. **Per-stage timings** for two camera rigs on one town:

   * the full FogDrive rig: 4 cameras at 1280×960 (``RigConfig.fogdrive()``);
   * a small RL rig: one 128×128 ``CAM_FRONT``.

   Each cell is the median in milliseconds with the p25–p75 range, taken over ``--repeats`` timed frames.
   The stages are:

   * the traffic step ``env.world.step(idle)``, which runs highway-env at 20 Hz with 10 Hz keyframes and
     skips highway-env's observation;
   * the scene build (``FogDriveEnv.build_scene``: ``world.vehicle_state()``, ``scene.vehicle_primitives()``
     and the ``Scene``), and its two sub-stages timed on their own;
   * ``CameraRig.primitives(scene)`` (props near the ego plus vehicles);
   * ``CameraRig.render(scene)`` for all cameras, batched;
   * each camera rendered alone by a one-camera ``CameraRig``;
   * the point sensors of the rig (LiDAR, semantic LiDAR, radar; both rigs have them by default):
     ``env.point_sensors.measure(scene, prims, rng, tick)`` on the same primitives as the cameras;
   * the wall time of a full ``env.step(idle)``, which covers the cameras and the point sensors.

   Below those come the steps per second, the reset time (median of 3) with the static-world build inside
   it, and the construction time. Last is the ratio of the full step to a bare highway-env step of the
   same scenario. The bare step is timed in alternation with ``env.step``, so both see the same
   machine load.
2. **Point sensors** on the ``highway`` town with packed traffic (60 vehicles, 5 lanes, density 12: ~50 within
   the LiDAR's range; no cameras), over ``--repeats`` steps of
   an episode (the env is stepped, untimed, between measurements): each of ``simulate_lidar``,
   ``simulate_semantic_lidar`` and ``simulate_radar`` alone, and all three through ``PointSensors.measure``,
   against the target of 10 ms per tick for all three. The same calls are then timed with 500 extra boxes
   appended to the primitives, all with their centres 310–600 m from the ego (every point of them beyond 300 m,
   out of every sensor's reach), in alternation with the plain calls. Their cost must not grow with such boxes,
   so the ratio should stay near 1.
3. **Bare highway-env baseline**. The first scenario uses the same scenario class and config as the town
   (``fog_gym.world.TOWN_SPECS``) at the same frequencies. It is reset with the seed that
   ``FogDriveEnv.reset(seed=0)`` gives its world, so it starts from the same traffic. The second is the
   ``highway`` town with ``vehicles_count=50``. The times are ``env.step`` including highway-env's own
   Kinematics observation. The observation (``observation_type.observe()``) is also timed on its own.
4. **cProfile shares** over about 10 bare highway-env steps: the time in ``Road.neighbour_vehicles`` and in
   the collision checks (``handle_collisions``, which includes ``_is_colliding``). Both are O(N²) pure
   Python. cProfile adds a cost to every Python call, so read these figures as shares, not absolute times.
5. **Scene size**: the vehicles, render primitives and points per channel per frame (median, with min–max).

Methodology:

* Before anything is timed, the script warms up. The first render compiles or loads the numba kernels,
  and the first frame builds the props cache.
* The idle action is ``1`` for a ``Discrete`` action space and zeros for a ``Box``.
* When an episode ends while frames are being timed (a crash, or the episode length), the env is reset.
  The reset is not timed, and it is counted in the "resets" column.
* The machine may be shared and noisy, so every figure is a median over repeats.

Usage::

    python scripts/bench.py                  # 20 timed frames per configuration, town "highway"
    python scripts/bench.py --quick          # smoke run (3 frames, 3 point-sensor steps)
    python scripts/bench.py --town merge --repeats 50 --json out/bench.json
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import platform
import pstats
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from fog_gym.config import TOWNS

DEFAULT_REPEATS = 20
QUICK_REPEATS = 3
RESET_REPEATS = 3
PROFILE_STEPS = 10
WARMUP_STEPS = 2
DENSE_VEHICLES = 50
FAR_BOXES = 500  # extra boxes out of every sensor's reach, for the out-of-range check
FAR_RADIUS = (310.0, 600.0)  # their centres' distance from the ego [m]; a box's nearest point stays beyond 300 m
POINT_SENSORS_TARGET_MS = 10.0  # LiDAR + semantic LiDAR + radar, per tick
CHANNEL_LABELS = {"LIDAR_TOP": "LiDAR", "SEM_LIDAR_TOP": "semantic LiDAR", "RADAR_FRONT": "radar"}

RIGS: dict[str, dict[str, Any]] = {
    # key: label, FogDriveEnv kwargs
    # (the point sensors of RigConfig.fogdrive() stay in both; bench_rig appends them to the label)
    "full": {"label": "full rig: 4 × 1280×960", "kwargs": {}},  # rig=None → RigConfig.fogdrive()
    "rl": {"label": "RL rig: 1 × 128×128", "kwargs": {"resolution": (128, 128), "cameras": ["CAM_FRONT"]}},
}


# -- small helpers ------------------------------------------------------------------------------------


POINT_SENSOR_TRAFFIC = {"vehicles_count": 60, "vehicles_density": 12, "lanes_count": 5}


def timed(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> tuple[Any, float]:
    """Call ``fn`` and return ``(result, elapsed milliseconds)``."""
    t0 = time.perf_counter_ns()
    out = fn(*args, **kwargs)
    return out, (time.perf_counter_ns() - t0) / 1e6


def summarize(samples: list[float]) -> dict[str, Any]:
    """Return the median, the p25/p75, the min/max and the raw samples (milliseconds)."""
    a = np.asarray(samples, dtype=np.float64)
    if a.size == 0:
        return {"n": 0}
    p25, med, p75 = np.percentile(a, [25, 50, 75])
    return {
        "n": int(a.size), "median": float(med), "p25": float(p25), "p75": float(p75),
        "min": float(a.min()), "max": float(a.max()), "samples": [round(float(x), 4) for x in a],
    }  # fmt: skip


def idle_action(space: Any) -> Any:
    """The idle action: IDLE (index 1) for highway-env's discrete meta-actions, zeros for continuous ones."""
    from gymnasium import spaces

    if isinstance(space, spaces.Discrete):
        return 1
    if isinstance(space, spaces.Box):
        return np.zeros(space.shape, space.dtype)
    raise TypeError(f"no idle action for action space {space!r}")


def fmt_ms(stat: dict[str, Any] | None) -> str:
    if not stat or not stat.get("n"):
        return "—"
    med = stat["median"]
    if stat["n"] == 1:
        return f"{med:.2f}"
    return f"{med:.2f} ({stat['p25']:.2f}–{stat['p75']:.2f})"


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(str(c).ljust(w) for c, w in zip(cells, widths)) + " |"

    sep = "|" + "|".join("-" * (w + 2) for w in widths) + "|"
    return "\n".join([line(header), sep, *(line(r) for r in rows)])


# -- FogDrive-v0 stages --------------------------------------------------------------------------------


def build_scene(env: Any) -> tuple[Any, dict[str, float]]:
    """``env.build_scene()`` (what ``step`` does before it renders), with its sub-stages timed separately."""
    from fog_gym.scene import vehicle_primitives
    from fog_gym.world import EGO_ID

    t0 = time.perf_counter_ns()
    state = env.world.vehicle_state()
    t1 = time.perf_counter_ns()
    vehicle_primitives(state, env.scene.lighting.night, exclude_id=EGO_ID)
    t2 = time.perf_counter_ns()
    scene = env.build_scene()
    t3 = time.perf_counter_ns()
    return scene, {"vehicle_state": (t1 - t0) / 1e6, "vehicle_primitives": (t2 - t1) / 1e6, "total": (t3 - t2) / 1e6}


def solo_rigs(env: Any) -> dict[str, Any]:
    """Make one single-camera ``CameraRig`` for each camera of the env's rig (same far plane)."""
    from fog_gym.config import RigConfig
    from fog_gym.sensors import CameraRig

    return {c.name: CameraRig(RigConfig((c,)), far=env.config.far_distance) for c in env.config.rig.cameras}


class EpisodeKeeper:
    """Reset the env (untimed) when an episode ends, and refresh the solo rigs' props caches after a reset."""

    def __init__(self, env: Any, solos: dict[str, Any]) -> None:
        self.env, self.solos = env, solos
        self.resets = 0
        self.steps = 0  # steps since the last reset

    def after_step(self, terminated: bool, truncated: bool = False) -> None:
        self.steps += 1
        if terminated or truncated or self.steps >= self.env.config.episode_steps:
            self.resets += 1
            self.steps = 0
            self.env.reset(seed=self.resets)
            for rig in self.solos.values():  # prop_primitives() is cached per static world: fill it now, untimed
                rig.primitives(self.env.scene)


def warm_up(env: Any, solos: dict[str, Any], action: Any) -> None:
    """Compile or load the numba kernels and fill the caches: reset, a few steps, one render per solo rig."""
    env.reset(seed=0)
    for _ in range(WARMUP_STEPS):
        env.step(action)
    scene, _ = build_scene(env)
    env.cameras.render(scene)
    for rig in solos.values():
        rig.render(scene)


def measure_reset(env: Any, repeats: int, desc: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """``env.reset(seed=0)`` wall time. Also time the static-world build inside it (road surface map + props)."""
    resets, static = [], []
    for _ in tqdm(range(repeats), desc=desc, unit="reset", leave=False):
        resets.append(timed(env.reset, seed=0)[1])
        static.append(timed(env._build_static, np.random.default_rng(0))[1])  # private: what reset() calls
    return summarize(resets), summarize(static)


def measure_stages(env: Any, solos: dict[str, Any], action: Any, repeats: int, desc: str) -> dict[str, Any]:
    """Time each stage of a frame: traffic step, scene build, primitives, batched render, solo renders."""
    keep = EpisodeKeeper(env, solos)
    t: dict[str, list[float]] = {k: [] for k in (
        "traffic_step", "vehicle_state", "vehicle_primitives", "scene_build", "rig_primitives", "cameras_batched",
        "point_sensors",
    )}  # fmt: skip
    for name in solos:
        t[f"camera:{name}"] = []
    counts: dict[str, list[int]] = {"vehicles": [], "vehicle_primitives": [], "render_primitives": [], "props": []}
    for ch in env.point_sensors.channels:
        counts[f"points:{ch}"] = []
    rng = np.random.default_rng(0)  # the bench's own draws: env._sensor_rng is left to env.step
    for _ in tqdm(range(repeats), desc=desc, unit="frame", leave=False):
        (_, terminated, _), ms = timed(env.world.step, action)
        t["traffic_step"].append(ms)
        scene, sub = build_scene(env)
        t["vehicle_state"].append(sub["vehicle_state"])
        t["vehicle_primitives"].append(sub["vehicle_primitives"])
        t["scene_build"].append(sub["total"])
        prims, ms = timed(env.cameras.primitives, scene)
        t["rig_primitives"].append(ms)
        _, ms = timed(env.cameras.render, scene)
        t["cameras_batched"].append(ms)
        for name, rig in solos.items():
            _, ms = timed(rig.render, scene)
            t[f"camera:{name}"].append(ms)
        points, ms = timed(env.point_sensors.measure, scene, prims, rng, sensor_tick(env))
        t["point_sensors"].append(ms)
        for ch, pts in points.items():
            counts[f"points:{ch}"].append(len(pts))
        counts["vehicles"].append(len(scene.vehicles))
        counts["vehicle_primitives"].append(len(scene.primitives))
        counts["render_primitives"].append(len(prims))
        counts["props"].append(len(scene.static.props))
        keep.after_step(terminated)
    out: dict[str, Any] = {k: summarize(v) for k, v in t.items()}
    out["counts"] = {
        k: {"median": float(np.median(v)), "min": int(min(v)), "max": int(max(v))} for k, v in counts.items()
    }
    out["resets"] = keep.resets
    return out


def sensor_tick(env: Any) -> int:
    """The simulation tick that the current keyframe closes (as ``FogDriveEnv._observe`` computes it)."""
    return max(env.world.tick - 1, 0)


def point_sensor_label(env: Any) -> str:
    chans = env.point_sensors.channels
    return " + " + ", ".join(CHANNEL_LABELS.get(c, c) for c in chans) if chans else " (no point sensors)"


def measure_env_step(env: Any, action: Any, bare: Any, repeats: int, desc: str) -> tuple[dict, dict]:
    """Wall time of ``env.step(action)``, alternating with a bare highway-env step of the same scenario.

    ``env.step`` covers the traffic, the scene, every camera, the point sensors and the observation dict. Both envs
    start from the same traffic, and each timed ``env.step`` is followed by one timed ``bare.step``. The two
    series therefore see the same machine load, and their ratio holds up when the load drifts.
    """
    from fog_gym.env import FogDriveEnv

    env.reset(seed=0)
    bare.reset(seed=FogDriveEnv.episode_seed_for(0))
    bare_action = idle_action(bare.action_space)
    keep = EpisodeKeeper(env, {})
    fog_ms, bare_ms, bare_resets = [], [], 0
    for _ in tqdm(range(repeats), desc=desc, unit="step", leave=False):
        (_, _, terminated, truncated, _), ms = timed(env.step, action)
        fog_ms.append(ms)
        keep.after_step(terminated, truncated)
        (_, _, terminated, truncated, _), ms = timed(bare.step, bare_action)
        bare_ms.append(ms)
        if terminated or truncated:
            bare_resets += 1
            bare.reset(seed=FogDriveEnv.episode_seed_for(bare_resets))
    return {**summarize(fog_ms), "resets": keep.resets}, {**summarize(bare_ms), "resets": bare_resets}


def bench_rig(town: str, rig_key: str, repeats: int) -> dict[str, Any]:
    from fog_gym.env import FogDriveEnv

    env, ms_init = timed(FogDriveEnv, town=town, **RIGS[rig_key]["kwargs"])
    label = RIGS[rig_key]["label"] + point_sensor_label(env)
    solos = solo_rigs(env)
    action = idle_action(env.action_space)
    warm_up(env, solos, action)
    result: dict[str, Any] = {
        "label": label, "cameras": list(env.cameras.names), "point_sensors": list(env.point_sensors.channels),
        "construct": summarize([ms_init]),
    }  # fmt: skip
    result["reset"], result["static_build"] = measure_reset(env, RESET_REPEATS, f"{rig_key}: reset")
    result["stages"] = measure_stages(env, solos, action, repeats, f"{rig_key}: stages")
    bare = bare_highway_env(town)
    result["env_step"], result["bare_step"] = measure_env_step(env, action, bare, repeats, f"{rig_key}: env.step")
    bare.close()
    env.close()
    return result


# -- night vs day camera rendering ---------------------------------------------------------------------


def night_twin(scene: Any) -> Any:
    """The same instant at night: same geometry, night lighting and lamp colours (street lamps, beams, exposure)."""
    import dataclasses

    from fog_gym.scene import Lighting, vehicle_primitives

    light = Lighting.for_time_of_day("night", np.random.default_rng(0))
    return dataclasses.replace(scene, lighting=light,
                               primitives=vehicle_primitives(scene.vehicles, True, exclude_id=scene.ego_id))


def bench_night(town: str, repeats: int) -> dict[str, Any]:
    """``CameraRig.render`` of the full rig by day and by night on the same scenes, timed in alternation."""
    from fog_gym.env import FogDriveEnv

    env = FogDriveEnv(town=town, time_of_day="day", labels=None)
    action = idle_action(env.action_space)
    env.reset(seed=0)
    day, night, lights = [], [], []
    for k in tqdm(range(repeats + WARMUP_STEPS), desc="night vs day cameras", file=sys.stderr):
        env.step(action)
        scene = env.scene
        twin = night_twin(scene)
        prims_day, prims_night = env.cameras.primitives(scene), env.cameras.primitives(twin)
        order = [(scene, prims_day, day), (twin, prims_night, night)]
        for sc, pr, sink in order if k % 2 == 0 else order[::-1]:
            _, ms = timed(env.cameras.render, sc, pr)
            if k >= WARMUP_STEPS:
                sink.append(ms)
        if k >= WARMUP_STEPS:
            lights.append(len(env.cameras.night_lights(twin)[1]))
    env.close()
    d, n = summarize(day), summarize(night)
    return {"day": d, "night": n, "ratio": n["median"] / d["median"], "lights": summarize([float(x) for x in lights]),
            "label": "full rig: 4 × 1280×960"}


def render_night(res: dict[str, Any], repeats: int) -> list[str]:
    return [
        f"### Night vs day camera rendering ({res['label']}, `CameraRig.render`, {repeats} frames, alternating)",
        "",
        markdown_table(["", "day", "night", "night / day"],
                       [["ms", fmt_ms(res["day"]), fmt_ms(res["night"]), f"{res['ratio']:.2f}×"]]),
        "",
        f"Lights in a night frame (street lamps + low beams within reach): median {res['lights']['median']:.0f}.",
    ]


def night_figure(res: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(4.5, 3.2), dpi=120)
    keys = ("day", "night")
    med = [res[k]["median"] for k in keys]
    err = [[res[k]["median"] - res[k]["p25"] for k in keys], [res[k]["p75"] - res[k]["median"] for k in keys]]
    ax.bar(keys, med, yerr=err, color=["#e0b040", "#304070"], capsize=6)
    ax.set_ylabel("CameraRig.render [ms] (median, p25–p75)")
    ax.set_title(f"{res['label']}: night / day = {res['ratio']:.2f}×", fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


# -- point sensors on a dense highway ------------------------------------------------------------------


def far_boxes(template: Any, ego_xy: np.ndarray, rng: np.random.Generator, n: int) -> Any:
    """``n`` car-sized boxes (``Primitives``) on the ground with their centres ``FAR_RADIUS`` from ``ego_xy``.

    Their nearest points lie beyond 300 m from the ego (a car box reaches under 3 m from its centre), out of the
    LiDARs' 120 m and of the radar's rays (under 303 m from the bumper). Static world (``insts`` 0), car tag.
    """
    from fog_gym.primitives import Primitives

    r = rng.uniform(*FAR_RADIUS, n)
    a = rng.uniform(0.0, 2.0 * np.pi, n)
    halves = np.tile([2.4, 1.0, 0.8], (n, 1))
    centers = np.c_[ego_xy[0] + r * np.cos(a), ego_xy[1] + r * np.sin(a), halves[:, 2]]
    tag = template.tags[template.insts > 0][:1]  # a vehicle's tag where there is one
    return Primitives.coerce({
        "centers": centers, "halves": halves, "yaws": rng.uniform(-np.pi, np.pi, n), "colors": np.full((n, 3), 0.5),
        "tags": np.full(n, tag[0] if tag.size else 14), "insts": np.zeros(n), "emissive": np.zeros(n, bool),
    })  # fmt: skip


def point_sensor_calls(env: Any, scene: Any, prims: dict[str, np.ndarray]) -> dict[str, Callable[[], Any]]:
    """One zero-argument call per sensor alone (as ``PointSensors.measure`` makes it), and ``"all"`` = ``measure``."""
    from fog_gym.lidar import sensor_to_world, simulate_lidar, simulate_radar, simulate_semantic_lidar
    from fog_gym.points import LIDAR, RADAR, SEMANTIC_LIDAR

    ps, rig, f = env.point_sensors, env.config.rig, env.point_sensors.simulation_frequency
    tick, surface = sensor_tick(env), scene.static.surface
    rng = np.random.default_rng(tick)  # the bench's own draws: env._sensor_rng is left to env.step
    calls: dict[str, Callable[[], Any]] = {}
    if rig.lidar is not None:
        cfg = rig.lidar
        calls[LIDAR] = lambda: simulate_lidar(cfg, sensor_to_world(cfg.pose, scene.ego_pose), prims, surface, rng, f,
                                              ps._start_angle(cfg, tick))  # fmt: skip
    if rig.semantic_lidar is not None:
        scfg = rig.semantic_lidar
        calls[SEMANTIC_LIDAR] = lambda: simulate_semantic_lidar(
            scfg, sensor_to_world(scfg.pose, scene.ego_pose), prims, surface, rng, f, ps._start_angle(scfg, tick))
    if rig.radar is not None:
        rcfg = rig.radar

        def radar() -> Any:
            ego_velocity = scene.vehicles.velocities[scene.vehicles.ids == scene.ego_id][0]
            return simulate_radar(rcfg, sensor_to_world(rcfg.pose, scene.ego_pose), prims, rng, scene.vehicles,
                                  ego_velocity, f)  # fmt: skip

        calls[RADAR] = radar
    calls["all"] = lambda: ps.measure(scene, prims, rng, tick)
    return calls


def rays_per_tick(env: Any) -> dict[str, int]:
    from fog_gym.lidar import lidar_directions
    from fog_gym.points import LIDAR, RADAR, SEMANTIC_LIDAR

    rig, f = env.config.rig, env.point_sensors.simulation_frequency
    out = {}
    for name, cfg in ((LIDAR, rig.lidar), (SEMANTIC_LIDAR, rig.semantic_lidar)):
        if cfg is not None:
            out[name] = int(lidar_directions(cfg, f).shape[0])
    if rig.radar is not None:
        out[RADAR] = rig.radar.rays_per_tick(f)
    return out


def bench_point_sensors(repeats: int) -> dict[str, Any]:
    """Point sensors on the ``highway`` town with ``DENSE_VEHICLES`` vehicles, without and with far boxes.

    The env has no cameras (the sensors only need ``cameras.primitives``, which does not depend on the cameras).
    After the warm-up, each repeat steps the env (untimed), then times every call on the plain primitives and on
    the primitives plus ``FAR_BOXES`` far boxes, the two in alternating order so both see the same load.
    """
    from fog_gym.env import FogDriveEnv

    # packed traffic (5 lanes, density 12) so that ~50 vehicles are within the LiDAR's 120 m, as the target asks
    env = FogDriveEnv(town="highway", cameras=[], highway_config=POINT_SENSOR_TRAFFIC)
    action = idle_action(env.action_space)
    box_rng = np.random.default_rng(1234)
    env.reset(seed=0)
    for _ in range(WARMUP_STEPS):
        env.step(action)
    warm_prims = env.cameras.primitives(env.scene)
    for variant in (warm_prims, concat_prims(warm_prims, far_boxes(warm_prims, env.scene.ego_pose[:2], box_rng, 1))):
        for call in point_sensor_calls(env, env.scene, variant).values():
            call()
    keep = EpisodeKeeper(env, {})
    keys = [*env.point_sensors.channels, "all"]
    t: dict[str, dict[str, list[float]]] = {v: {k: [] for k in keys} for v in ("near", "far")}
    counts: dict[str, list[int]] = {"vehicles": [], "within_lidar_range": [], "prims": [], "prims_far": [],
                                    **{f"points:{c}": [] for c in env.point_sensors.channels}}  # fmt: skip
    same_points: dict[str, bool] = {}
    lidar_range = env.config.rig.lidar.range if env.config.rig.lidar is not None else 120.0
    for i in tqdm(range(repeats), desc="point sensors", unit="step", leave=False):
        _, _, terminated, truncated, _ = env.step(action)
        scene = env.scene
        prims = env.cameras.primitives(scene)
        ego_xy = np.asarray(scene.ego_pose[:2])
        with_far = concat_prims(prims, far_boxes(prims, ego_xy, box_rng, FAR_BOXES))
        variants = [("near", prims), ("far", with_far)]
        sweeps: dict[str, dict[str, np.ndarray]] = {}
        for variant, p in variants if i % 2 == 0 else variants[::-1]:
            for key, call in point_sensor_calls(env, scene, p).items():
                out, ms = timed(call)
                t[variant][key].append(ms)
                if key == "all":
                    sweeps[variant] = out
        for ch, pts in sweeps["near"].items():
            counts[f"points:{ch}"].append(len(pts))
            # same seed for both variants: out-of-range boxes must not change a single point
            same_points[ch] = same_points.get(ch, True) and np.array_equal(pts, sweeps["far"][ch])
        others = scene.vehicles.ids != scene.ego_id
        dist = np.hypot(*(scene.vehicles.centers[others, :2] - ego_xy).T)
        counts["vehicles"].append(len(scene.vehicles.ids))
        counts["within_lidar_range"].append(int(np.count_nonzero(dist <= lidar_range)))
        counts["prims"].append(len(prims))
        counts["prims_far"].append(len(with_far))
        keep.after_step(terminated, truncated)
    result = {
        "label": f"highway, {POINT_SENSOR_TRAFFIC}, no cameras",
        "lidar_range": lidar_range, "far_boxes": FAR_BOXES, "far_radius": list(FAR_RADIUS),
        "target_ms": POINT_SENSORS_TARGET_MS, "rays_per_tick": rays_per_tick(env), "resets": keep.resets,
        "same_points_with_far_boxes": same_points,
        "near": {k: summarize(v) for k, v in t["near"].items()}, "far": {k: summarize(v) for k, v in t["far"].items()},
        "counts": {k: {"median": float(np.median(v)), "min": int(min(v)), "max": int(max(v))}
                   for k, v in counts.items() if v},
    }  # fmt: skip
    env.close()
    return result


def concat_prims(*groups: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    from fog_gym.primitives import Primitives

    return Primitives.concat(*groups)


# -- bare highway-env ----------------------------------------------------------------------------------


def bare_highway_env(town: str, **overrides: Any) -> Any:
    """The town's highway-env scenario with fog-gym's config and frequencies (``fog_gym.world.highway_env_config``),
    with the observation kept."""
    import highway_env.envs as hw_envs

    from fog_gym.config import FogDriveConfig
    from fog_gym.world import TOWN_SPECS, highway_env_config

    defaults = FogDriveConfig()
    config = highway_env_config(town, defaults.simulation_frequency, defaults.keyframe_frequency, overrides)
    return getattr(hw_envs, TOWN_SPECS[town].env_class)(config=config)


def measure_bare(hw: Any, repeats: int, desc: str, seed: int = 0) -> dict[str, Any]:
    """``hw.step(idle)`` wall time (observation included), and ``observe()`` timed alone after each step."""
    action = idle_action(hw.action_space)
    hw.reset(seed=seed)
    for _ in range(WARMUP_STEPS):
        hw.step(action)
    steps, observe, resets, n_vehicles = [], [], 0, []
    for _ in tqdm(range(repeats), desc=desc, unit="step", leave=False):
        (_, _, terminated, truncated, _), ms = timed(hw.step, action)
        steps.append(ms)
        observe.append(timed(hw.observation_type.observe)[1])
        n_vehicles.append(len(hw.road.vehicles))
        if terminated or truncated:
            resets += 1
            hw.reset(seed=resets)
    return {
        "step": summarize(steps), "observe": summarize(observe), "resets": resets,
        "vehicles": float(np.median(n_vehicles)),
        "substeps": int(hw.config["simulation_frequency"] // hw.config["policy_frequency"]),
    }  # fmt: skip


def profile_bare(hw: Any, steps: int) -> dict[str, Any]:
    """Run cProfile over ``steps`` highway-env steps. Return the share of profiled time in the O(N²) helpers."""
    action = idle_action(hw.action_space)
    hw.reset(seed=0)
    hw.step(action)
    prof = cProfile.Profile()
    resets = 0
    for _ in tqdm(range(steps), desc="profile", unit="step", leave=False):
        prof.enable()
        _, _, terminated, truncated, _ = hw.step(action)
        prof.disable()
        if terminated or truncated:  # the reset is not profiled
            resets += 1
            hw.reset(seed=resets)
    stats = pstats.Stats(prof)
    total = stats.total_tt  # seconds, sum of own times = all profiled time
    found: dict[str, dict[str, float]] = {}
    for (filename, _, funcname), (_, ncalls, _, cumtime, _) in stats.stats.items():
        if funcname in ("neighbour_vehicles", "handle_collisions", "_is_colliding") and "highway_env" in filename:
            f = found.setdefault(funcname, {"cumtime": 0.0, "calls": 0})
            f["cumtime"] += cumtime
            f["calls"] += ncalls
    return {
        "steps": steps, "resets": resets, "total_s": total,
        **{
            name: {
                "share": found.get(name, {}).get("cumtime", 0.0) / total if total else 0.0,
                "calls_per_step": found.get(name, {}).get("calls", 0) / steps,
            }
            for name in ("neighbour_vehicles", "handle_collisions", "_is_colliding")
        },
    }  # fmt: skip


def bench_baselines(town: str, repeats: int, profile_steps: int) -> dict[str, Any]:
    """Bare highway-env for the town's config and for a dense highway (50 vehicles). Both are timed and profiled."""
    from fog_gym.env import FogDriveEnv
    from fog_gym.world import TOWN_SPECS, apply_idm_profile

    out: dict[str, Any] = {}
    configs = {
        # the town as FogDrive-v0 runs it, from the same initial traffic as FogDriveEnv.reset(seed=0)
        "town": (f"{town} ({TOWN_SPECS[town].env_class}, fog-gym config)", town, {}, FogDriveEnv.episode_seed_for(0)),
        # the highway town with more vehicles: 1 ego + 50 others
        "dense": (f"highway, vehicles_count={DENSE_VEHICLES}", "highway", {"vehicles_count": DENSE_VEHICLES}, 0),
    }
    for key, (label, t, overrides, seed) in configs.items():
        apply_idm_profile(t)  # the last world stepped may have left another town's IDM constants
        hw = bare_highway_env(t, **overrides)
        res = measure_bare(hw, repeats, f"bare {key}: step", seed)
        res["profile"] = profile_bare(hw, profile_steps)
        res["label"] = label
        res["config"] = {k: v for k, v in hw.config.items() if isinstance(v, (int, float, str, bool))}
        hw.close()
        out[key] = res
    return out


# -- report --------------------------------------------------------------------------------------------


def camera_keys(rig_result: dict[str, Any]) -> list[str]:
    return [f"camera:{n}" for n in rig_result["cameras"]]


def sum_medians(rig_result: dict[str, Any], keys: Any) -> float:
    return sum(rig_result["stages"][k]["median"] for k in keys)


STEP_STAGES = ("traffic_step", "scene_build", "cameras_batched", "point_sensors")


def render_point_sensors(ps: dict[str, Any], repeats: int) -> list[str]:
    c = ps["counts"]

    def count(key: str) -> str:
        return f"{c[key]['median']:.0f} ({c[key]['min']}–{c[key]['max']})" if key in c else "—"

    out = [
        f"## Point sensors per tick ({ps['label']}): ms, median (p25–p75), {repeats} steps",
        "",
        f"Vehicles (incl. ego): {count('vehicles')}; other vehicles within the LiDAR range ({ps['lidar_range']:.0f} m) "
        f"of the ego: {count('within_lidar_range')}; primitives: {count('prims')} (props within 600 m + vehicles), "
        f"{count('prims_far')} with the {ps['far_boxes']} far boxes (centres {ps['far_radius'][0]:.0f}–"
        f"{ps['far_radius'][1]:.0f} m from the ego). Episode resets while timing (untimed): {ps['resets']}.",
        "",
    ]
    rows = []
    near, far, target = ps["near"], ps["far"], ps["target_ms"]
    for key in [k for k in near if k != "all"]:
        rows.append([f"{CHANNEL_LABELS.get(key, key)} `{key}` alone", f"{ps['rays_per_tick'].get(key, 0)}",
                     count(f"points:{key}"), fmt_ms(near[key]), fmt_ms(far[key]),
                     f"{far[key]['median'] / near[key]['median']:.2f}×", ""])  # fmt: skip
    alone = sum(near[k]["median"] for k in near if k != "all")
    rows.append(["  sum of the sensors alone (medians)", "", "", f"{alone:.2f}",
                 f"{sum(far[k]['median'] for k in far if k != 'all'):.2f}", "", ""])  # fmt: skip
    ok = "met" if near["all"]["median"] <= target else "**missed**"
    ratio = far["all"]["median"] / near["all"]["median"]
    rows.append(["**all three: `point_sensors.measure`**", f"{sum(ps['rays_per_tick'].values())}", "",
                 f"**{fmt_ms(near['all'])}**", fmt_ms(far["all"]), f"**{ratio:.2f}×**",
                 f"≤ {target:.0f} ms: {ok}"])  # fmt: skip
    out.append(markdown_table(
        ["sensor", "rays / tick", "points / tick", "ms", f"ms, + {ps['far_boxes']} boxes > 300 m", "ratio far / plain",
         "target"], rows))  # fmt: skip
    same = ps.get("same_points_with_far_boxes", {})
    differ = [c for c, ok in same.items() if not ok]
    out += ["", "The far boxes lie out of every sensor's reach, so the ratio should stay near 1: the ray caster "
            "drops boxes beyond its range before binning them. With the same seed, the sweeps with the far boxes "
            + ("are identical to those without, in every channel and step." if same and not differ else
               f"**differ** from those without in {', '.join(differ)}." if differ else "were not compared.")]
    return out


def bench_fog(repeats: int) -> dict[str, Any]:
    """Fog stages on one real full-rig frame: camera fog per 1280×960 image, LiDAR fog per 100 k points, and the
    full paired frame (4 cameras × 3 levels + 3 LiDAR levels) as ``FogWrapper`` computes it."""
    from fog_gym.env import FogDriveEnv
    from fog_gym.fog import atmospheric_light, fog_image, fog_images, fog_lidar, parse_fog
    from fog_gym.points import unpack_points
    from fog_gym.wrappers import FogWrapper

    levels = ("light", "moderate", "dense")
    env = FogWrapper(FogDriveEnv(town="highway"), list(levels))
    obs, _ = env.reset(seed=0)
    base = env.unwrapped
    K = base.intrinsics["CAM_FRONT"]
    rgb, depth = base.frames["CAM_FRONT"].rgb, base.frames["CAM_FRONT"].depth
    airlight = env.airlight["CAM_FRONT"]
    clean_lidar = base.points["LIDAR_TOP"]
    rng = np.random.default_rng(0)
    r = rng.uniform(1.5, 120.0, 100_000)
    az, el = rng.uniform(-np.pi, np.pi, r.size), rng.uniform(-0.35, 0.09, r.size)
    cloud = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el), np.exp(-0.004 * r)]
    cloud = cloud.astype(np.float32)
    alphas = [parse_fog(lv).alpha for lv in levels]
    calls: dict[str, Callable[[], Any]] = {
        **{f"camera fog, 1 image, {lv}": (lambda a=parse_fog(lv).alpha: fog_image(rgb, depth, K, a, airlight))
           for lv in levels},
        "camera fog, 1 image, 3 levels in one pass": lambda: fog_images(rgb, depth, K, alphas, airlight),
        "LiDAR fog, 100 k points, dense": lambda: fog_lidar(cloud, parse_fog("dense"), rng),
        f"LiDAR fog, this frame's sweep ({len(clean_lidar)} points), dense": lambda: fog_lidar(
            clean_lidar, parse_fog("dense"), rng),
        "atmospheric light estimate, 1 image (once per episode)": lambda: atmospheric_light(rgb),
        "**full paired frame: 4 cameras × 3 levels + 3 LiDAR levels**": lambda: env._fogged(obs, env.levels),
    }  # fmt: skip
    for fn in calls.values():  # warm-up (compiles)
        fn()
    stats = {}
    for name, fn in tqdm(calls.items(), desc="fog stages", unit="stage", file=sys.stderr):
        stats[name] = summarize([timed(fn)[1] for _ in range(repeats)])
    env.close()
    assert unpack_points(obs, "LIDAR_TOP_FOG_DENSE").shape == clean_lidar.shape
    return {"stages": stats, "lidar_points": int(len(clean_lidar)), "targets": {"LiDAR 100k": 5.0, "paired frame": 20.0}}


def render_fog(fog: dict[str, Any], repeats: int) -> list[str]:
    rows = [[name, fmt_ms(stat)] for name, stat in fog["stages"].items()]
    return [f"## Fog (full rig, highway, seed 0): ms, median (p25–p75), {repeats} repeats", "",
            markdown_table(["stage", "ms"], rows), "",
            "Targets: LiDAR fog on 100 k points ≤ 5 ms; full paired frame ≤ 20 ms (2-core CPU)."]  # fmt: skip


def bench_labels(repeats: int) -> dict[str, Any]:
    """Ground truth for all four 1280×960 cameras (``env.ground_truth()``), both visibility rules, packed traffic."""
    from fog_gym.env import FogDriveEnv

    out: dict[str, Any] = {}
    for rule in ("lidar", "camera"):
        env = FogDriveEnv(town="highway", visibility=rule, highway_config=POINT_SENSOR_TRAFFIC)
        env.reset(seed=0)
        samples, boxes, near = [], [], []
        for _ in tqdm(range(repeats + WARMUP_STEPS), desc=f"labels ({rule})", unit="frame", leave=False, file=sys.stderr):
            _, _, terminated, truncated, _ = env.step(idle_action(env.action_space))
            if terminated or truncated:
                env.reset()
            gt, ms = timed(env.ground_truth)
            samples.append(ms)
            boxes.append(sum(len(b["vehicle_ids"]) for b in gt["boxes_2d"].values()))
            v = env.scene.vehicles
            near.append(int((np.hypot(*(v.centers[1:, :2] - np.asarray(env.scene.ego_pose[:2])).T) <= 120.0).sum()))
        out[rule] = {"ms": summarize(samples[WARMUP_STEPS:]), "boxes_2d": float(np.median(boxes)),
                     "vehicles_within_120m": float(np.median(near))}  # fmt: skip
        env.close()
    return out


def render_labels(lab: dict[str, Any], repeats: int) -> list[str]:
    rows = [[f"`visibility=\"{rule}\"`", f"{r['vehicles_within_120m']:.0f}", f"{r['boxes_2d']:.0f}", fmt_ms(r["ms"])]
            for rule, r in lab.items()]  # fmt: skip
    return [f"## Ground truth, 4 cameras × 1280×960 (highway, {POINT_SENSOR_TRAFFIC}): ms per frame, {repeats} frames", "",
            markdown_table(["rule", "vehicles within 120 m", "2D boxes (all cameras)", "ms"], rows), "",
            "Target: ≤ 2 ms per frame with ~50 vehicles."]  # fmt: skip


def bench_recording(repeats: int) -> dict[str, Any]:
    """Recording one full paired frame: the PNG-encoder bound (the 24 images of D2) against the recorder's whole
    per-frame cost (every file encoded and written atomically), and ``fog-gym generate`` scaling with workers."""
    import tempfile

    from fog_gym.generate import generate, plan_scenes
    from fog_gym.dataset.writer import SceneWriter, encode_png
    from fog_gym.encoding import encode_depth, semantic_to_carla_rgb
    from fog_gym.env import FogDriveEnv
    from fog_gym.wrappers import FogWrapper

    env = FogWrapper(FogDriveEnv(town="highway"), ["light", "moderate", "dense"])
    obs, info = env.reset(seed=0)
    images = []
    for cam in ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT"):
        images += [obs[cam]] + [obs[f"{cam}_FOG_{lv}"] for lv in ("LIGHT", "MODERATE", "DENSE")]
        images += [encode_depth(obs[f"{cam}_DEPTH"]), semantic_to_carla_rgb(obs[f"{cam}_SEM"])]
    with tempfile.TemporaryDirectory() as tmp:
        writer = SceneWriter(tmp, "data_collection_T1_day_run1_00000000")
        bound, record, sizes = [], [], []
        for i in tqdm(range(max(3, repeats // 4)), desc="recording", unit="frame", leave=False, file=sys.stderr):
            bound.append(timed(lambda: [encode_png(im) for im in images])[1])
            files, ms_encode = timed(writer.encode_sample, obs, info)
            _, ms_write = timed(writer.write_files, i, files)
            record.append(ms_encode + ms_write)
            sizes.append(sum(len(b) for b in files.values()) / 1e6)
    env.close()
    scaling = {}
    plan = plan_scenes(4, towns=("merge", "roundabout"), seed=0, resolution=(640, 480), seconds=3.0)
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as tmp:
            _, ms = timed(generate, tmp, plan, workers, False, None, False)
            scaling[workers] = ms / 1000.0
    return {"bound": summarize(bound), "recorder": summarize(record), "mb_per_frame": float(np.median(sizes)),
            "generate_s": scaling}  # fmt: skip


def render_recording(rec: dict[str, Any]) -> list[str]:
    ratio = rec["recorder"]["median"] / rec["bound"]["median"]
    s1, s2 = rec["generate_s"][1], rec["generate_s"][2]
    return ["## Recording (full rig, clean + 3 paired fog levels)", "",
            markdown_table(["stage", "ms per frame"], [
                ["PNG-encoder bound: the 24 PNGs of one sample (cv2, zlib 1, no filter)", fmt_ms(rec["bound"])],
                ["recorder: all 35 files encoded + written atomically", fmt_ms(rec["recorder"])],
                ["**ratio recorder / bound**", f"**{ratio:.2f}×** (target ≤ 1.3×)"],
                ["bytes per sample", f"{rec['mb_per_frame']:.1f} MB"]]), "",
            f"`fog-gym generate`, 4 scenes × 3 s at 640×480 (incl. process start and kernel load): 1 worker "
            f"{s1:.1f} s, 2 workers {s2:.1f} s ({s1 / s2:.2f}× faster)."]  # fmt: skip


def bench_rl(repeats: int) -> dict[str, Any]:
    """``FogDriveRL-v0`` (dense fog) steps/s — one env, and 2 async subprocess envs — next to bare highway-env of
    the same scenario and frequencies (20 Hz sim, 5 Hz policy, 20 vehicles, 3 lanes), and the share of the step
    spent on sensors + fog + observation shaping."""
    import gymnasium as gym

    import fog_gym  # noqa: F401
    from fog_gym.rl import RL_TRAFFIC

    n = max(40, repeats * 5)

    def rate(env, batch: int = 1) -> float:
        env.reset(seed=0)
        action = np.ones(batch, np.int64) if batch > 1 else 1
        for _ in range(3):
            env.step(action)
        t0 = time.perf_counter()
        for _ in range(n):
            out = env.step(action)
            if batch == 1 and (out[2] or out[3]):
                env.reset()
        return batch * n / (time.perf_counter() - t0)

    single = gym.make("FogDriveRL-v0", fog="dense")
    fog_rate = rate(single)
    base = single.unwrapped
    world_ms = [timed(base.world.step, 1)[1] for _ in range(n)]
    single.close()
    vec = gym.make_vec("fog_gym:FogDriveRL-v0", num_envs=2, vectorization_mode="async", fog="dense")
    vec_rate = rate(vec, 2)
    vec.close()
    hw = bare_highway_env("highway", **RL_TRAFFIC, policy_frequency=5)
    bare_rate = rate(hw)
    hw_vec = gym.vector.AsyncVectorEnv([lambda: bare_highway_env("highway", **RL_TRAFFIC, policy_frequency=5)] * 2)
    bare_vec_rate = rate(hw_vec, 2)
    hw_vec.close()
    step_ms = 1000.0 / fog_rate
    traffic_ms = float(np.median(world_ms))
    return {"fog_steps_per_s": fog_rate, "fog_vec2_steps_per_s": vec_rate, "bare_steps_per_s": bare_rate,
            "bare_vec2_steps_per_s": bare_vec_rate, "step_ms": step_ms, "traffic_ms": traffic_ms,
            "sensor_share": max(0.0, 1.0 - traffic_ms / step_ms)}  # fmt: skip


def render_rl(rl: dict[str, Any]) -> list[str]:
    return ["## RL preset `FogDriveRL-v0` (dense fog; 64×64 camera + 32-channel LiDAR BEV; 20 Hz sim, 5 Hz policy)", "",
            markdown_table(["", "1 env", "2 async subprocess envs"], [
                ["FogDriveRL-v0 steps/s", f"{rl['fog_steps_per_s']:.1f}", f"{rl['fog_vec2_steps_per_s']:.1f}"],
                ["bare highway-env steps/s (same scenario, 20/5 Hz, Kinematics obs)", f"{rl['bare_steps_per_s']:.1f}",
                 f"{rl['bare_vec2_steps_per_s']:.1f}"]]), "",
            f"Step {rl['step_ms']:.1f} ms, of which traffic {rl['traffic_ms']:.1f} ms: sensors + fog + shaping take "
            f"{rl['sensor_share']:.0%} of the step (target ≤ 25 %)."]  # fmt: skip


def render_report(results: dict[str, Any]) -> str:
    meta, rigs, base = results["meta"], results["rigs"], results["baseline"]
    keys = list(rigs)
    bare_ms = base["town"]["step"]["median"]
    out = [
        f"# fog-gym benchmark: town `{meta['town']}`",
        "",
        f"{meta['repeats']} timed frames per configuration · {meta['cpu_count']} CPUs, numba {meta['numba']} "
        f"({meta['numba_threads']} threads, {meta['numba_layer']} layer) · highway-env {meta['highway_env']} · "
        f"Python {meta['python']} · "
        f"{meta['platform']}",
        "",
        f"Load average (1/5/15 min) at start {meta['loadavg_start']}, at end {meta['loadavg_end']}; "
        f"wall time {meta['wall_s']:.0f} s. Another busy process on this machine inflates every figure, the numba "
        "kernels' parallel joins most of all.",
        "",
        "## FogDrive-v0 per-stage timings: ms, median (p25–p75)",
        "",
    ]
    cam_names = []
    for k in keys:
        cam_names += [c for c in rigs[k]["cameras"] if c not in cam_names]

    def row(label: str, get: Callable[[dict[str, Any]], str]) -> list[str]:
        return [label, *(get(rigs[k]) for k in keys)]

    rows = [
        row("env construction (once)", lambda r: fmt_ms(r["construct"])),
        row(f"env.reset(seed=0) (median of {RESET_REPEATS})", lambda r: fmt_ms(r["reset"])),
        row("  static world build alone (`_build_static`)", lambda r: fmt_ms(r["static_build"])),
        row("traffic step: `world.step` (2 × 20 Hz sub-steps, no obs)", lambda r: fmt_ms(r["stages"]["traffic_step"])),
        row("  scene: `world.vehicle_state()`", lambda r: fmt_ms(r["stages"]["vehicle_state"])),
        row("  scene: `vehicle_primitives()`", lambda r: fmt_ms(r["stages"]["vehicle_primitives"])),
        row("scene build (state + primitives + `Scene`)", lambda r: fmt_ms(r["stages"]["scene_build"])),
        row("`cameras.primitives(scene)` (inside render)", lambda r: fmt_ms(r["stages"]["rig_primitives"])),
        row("cameras (all, batched): `cameras.render`", lambda r: fmt_ms(r["stages"]["cameras_batched"])),
    ]
    for name in cam_names:
        rows.append(row(f"  camera {name} alone", lambda r, n=name: fmt_ms(r["stages"].get(f"camera:{n}"))))
    rows.append(row("  sum of cameras alone (medians)", lambda r: f"{sum_medians(r, camera_keys(r)):.2f}"))
    rows.append(row("point sensors: `point_sensors.measure` (same prims)",
                    lambda r: fmt_ms(r["stages"]["point_sensors"])))
    rows.append(row("traffic + scene + cameras + point sensors (sum of medians)",
                    lambda r: f"{sum_medians(r, STEP_STAGES):.2f}"))
    rows.append(row("**full `env.step`** (cameras + point sensors)", lambda r: f"**{fmt_ms(r['env_step'])}**"))
    rows.append(row("env steps / s (1000 / median)", lambda r: f"{1000.0 / r['env_step']['median']:.1f}"))
    rows.append(row("bare highway-env step, same scenario (with obs), interleaved",
                    lambda r: fmt_ms(r["bare_step"])))
    rows.append(row("**ratio: FogDrive-v0 step / bare step**",
                    lambda r: f"**{r['env_step']['median'] / r['bare_step']['median']:.2f}×**"))
    rows.append(row("ratio: traffic step / bare step (separate runs)",
                    lambda r: f"{r['stages']['traffic_step']['median'] / bare_ms:.2f}×"))
    rows.append(row("episode resets while timing (untimed)",
                    lambda r: str(sum(r[k]["resets"] for k in ("stages", "env_step", "bare_step")))))
    out.append(markdown_table(["stage", *(rigs[k]["label"] for k in keys)], rows))

    out += ["", "## Scene size per frame: median (min–max)", ""]

    def count(r: dict[str, Any], key: str) -> str:
        c = r["stages"]["counts"][key]
        return f"{c['median']:.0f} ({c['min']}–{c['max']})"

    rows = [
        row("vehicles (incl. ego)", lambda r: count(r, "vehicles")),
        row("vehicle primitives (ego excluded)", lambda r: count(r, "vehicle_primitives")),
        row("static props in the episode", lambda r: count(r, "props")),
        row("render primitives (props near ego + vehicles)", lambda r: count(r, "render_primitives")),
    ]
    for ch in CHANNEL_LABELS:
        key = f"points:{ch}"
        if any(key in rigs[k]["stages"]["counts"] for k in keys):
            rows.append(row(f"{CHANNEL_LABELS[ch]} points `{ch}`",
                            lambda r, k=key: count(r, k) if k in r["stages"]["counts"] else "—"))
    out.append(markdown_table(["", *(rigs[k]["label"] for k in keys)], rows))

    if results.get("point_sensors"):
        out += ["", *render_point_sensors(results["point_sensors"], meta["repeats"])]

    out += ["", f"## Bare highway-env (observation included): ms, median (p25–p75), {meta['repeats']} steps", ""]
    rows = []
    for b in base.values():
        sub = b["substeps"]
        rows.append([
            b["label"], f"{b['vehicles']:.0f}", fmt_ms(b["step"]), f"{b['step']['median'] / sub:.2f}",
            fmt_ms(b["observe"]), f"{b['step']['median'] - b['observe']['median']:.2f}",
        ])  # fmt: skip
    out.append(markdown_table(
        ["scenario (20 Hz sim, 10 Hz policy)", "vehicles", "env.step", "per 20 Hz sub-step", "Kinematics observe()",
         "step − observe"], rows))  # fmt: skip

    prof_steps = next(iter(base.values()))["profile"]["steps"]
    out += ["", f"## cProfile over {prof_steps} bare highway-env steps: share of profiled time (calls / step)", ""]
    rows = []
    for b in base.values():
        p = b["profile"]
        cell = lambda name: f"{100 * p[name]['share']:.1f} % ({p[name]['calls_per_step']:.0f})"  # noqa: E731
        rows.append([b["label"], f"{p['total_s'] * 1000 / p['steps']:.1f}", cell("neighbour_vehicles"),
                     cell("handle_collisions"), cell("_is_colliding")])  # fmt: skip
    out.append(markdown_table(
        ["scenario", "profiled ms / step", "`Road.neighbour_vehicles`", "`handle_collisions` (incl. below)",
         "`_is_colliding`"], rows))  # fmt: skip
    out += ["", "cProfile slows every Python call, so its ms / step is higher than the timings above. Read the "
            "percentages as shares of highway-env's Python time (the shares are cumulative and can overlap)."]
    return "\n".join(out)


# -- main ----------------------------------------------------------------------------------------------


def load_average() -> list[float] | None:
    """1-, 5- and 15-minute load averages (None where the OS has none). Noise from other processes shows here."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def build_parser(prog: str = "bench.py") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Per-stage milliseconds of FogDrive-v0 (traffic step, scene build, cameras batched and alone, "
        "point sensors, full env.step) for the full 4×1280×960 rig and a 1×128×128 RL rig (both with LiDAR, "
        "semantic LiDAR and radar), against a bare highway-env step; the point sensors alone on a 50-vehicle "
        "highway, with and without 500 boxes out of range. "
        "It prints Markdown tables and asserts nothing.",
    )
    parser.add_argument("--repeats", type=positive_int, default=None,
                        help=f"timed frames per configuration (default {DEFAULT_REPEATS}; "
                        f"{QUICK_REPEATS} with --quick)")
    parser.add_argument("--town", choices=TOWNS, default="highway", help="fog-gym town (default highway)")
    parser.add_argument("--quick", action="store_true", help=f"smoke run: {QUICK_REPEATS} repeats, 3 profiled steps")
    parser.add_argument("--json", type=Path, default=None, metavar="PATH",
                        help="also write every figure (with the raw samples) as JSON to PATH")  # fmt: skip
    parser.add_argument("--night-only", action="store_true",
                        help="only time the full rig's cameras by night against by day (same scenes)")
    parser.add_argument("--night-figure", type=Path, default=None, metavar="PNG",
                        help="write the night vs day camera bar chart to PNG")
    return parser


def main(argv: list[str] | None = None, prog: str = "bench.py") -> int:
    args = build_parser(prog).parse_args(argv)
    repeats = args.repeats or (QUICK_REPEATS if args.quick else DEFAULT_REPEATS)
    profile_steps = 3 if args.quick else PROFILE_STEPS

    import highway_env
    import numba

    import fog_gym.env  # noqa: F401  (import everything up front: module imports are not env construction)

    try:
        from importlib.metadata import version

        hw_version = version("highway-env")
    except Exception:  # pragma: no cover - metadata missing in odd installs
        hw_version = getattr(highway_env, "__version__", "?")
    meta = {
        "town": args.town, "repeats": repeats, "quick": args.quick, "profile_steps": profile_steps,
        "cpu_count": os.cpu_count(), "numba": numba.__version__, "numba_threads": numba.get_num_threads(),
        "highway_env": hw_version, "python": platform.python_version(), "platform": platform.platform(terse=True),
        "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "loadavg_start": load_average(),
    }  # fmt: skip

    t0 = time.perf_counter()
    night = bench_night(args.town, repeats)
    if args.night_figure is not None:
        night_figure(night, args.night_figure)
    if args.night_only:
        print("\n".join(render_night(night, repeats)))
        if args.json is not None:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps({"meta": meta, "night": night}, indent=2))
        return 0
    rigs = {key: bench_rig(args.town, key, repeats) for key in RIGS}
    point_sensors = bench_point_sensors(repeats)
    fog = bench_fog(repeats)
    labels = bench_labels(repeats)
    recording = bench_recording(repeats)
    rl = bench_rl(repeats)
    baseline = bench_baselines(args.town, repeats, profile_steps)
    meta.update(wall_s=time.perf_counter() - t0, loadavg_end=load_average(), numba_layer=numba.threading_layer())
    results = {"meta": meta, "rigs": rigs, "point_sensors": point_sensors, "fog": fog, "labels": labels, "recording": recording, "rl": rl,
               "baseline": baseline, "night": night}

    print(render_report(results))
    print("\n" + "\n".join(render_fog(fog, repeats)))
    print("\n" + "\n".join(render_labels(labels, repeats)))
    print("\n" + "\n".join(render_recording(recording)))
    print("\n" + "\n".join(render_rl(rl)))
    print("\n" + "\n".join(render_night(night, repeats)))
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(results, indent=2))
        print(f"\nwrote {args.json}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
