"""Per-stage timing of FogDrive-v0 against bare highway-env. This script only reports numbers and never
asserts a timing. It prints Markdown tables to stdout; progress bars go to stderr.

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

   Below those come the steps per second, the reset time (median of 3) with the static-world build
   (``env.build_static_world``) inside it, and the construction time. Last is the ratio of the full step to a
   bare highway-env step of the same scenario (``fog_gym.world.towns.highway_env_config``). The bare step is timed in
   alternation with ``env.step``, so both see the same machine load.
2. **Bare highway-env baseline**. The first scenario is the town's (``fog_gym.world.towns.highway_env_config``: the
   same scenario class, config and frequencies as ``TrafficWorld``), reset with the seed that
   ``FogDriveEnv.reset(seed=0)`` gives its world (``FogDriveEnv.episode_seed_for(0)``), so it starts from the same
   traffic. The
   second is the ``highway`` town with ``vehicles_count=50``. The times are ``env.step`` including highway-env's
   own Kinematics observation. The observation (``observation_type.observe()``) is also timed on its own.
3. **cProfile shares** over about 10 bare highway-env steps: the time in ``Road.neighbour_vehicles`` and in
   the collision checks (``handle_collisions``, which includes ``_is_colliding``). Both are O(N²) pure
   Python. cProfile adds a cost to every Python call, so read these figures as shares, not absolute times.
4. **Scene size**: the vehicles, render primitives and points per channel per frame (median, with min–max).
5. **RL preset** ``FogDriveRL-v0`` (dense fog) steps/s, one env and 2 async envs, next to bare highway-env.

Methodology:

* Before anything is timed, the script warms up. The first render compiles or loads the numba kernels,
  and the first frame builds the props cache.
* The idle action is ``env.idle_action`` (bare highway-env: ``1`` for ``Discrete``, zeros for ``Box``).
* When an episode ends while frames are being timed (a crash, or the episode length), the env is reset.
  The reset is not timed, and it is counted in the "resets" column.
* The machine may be shared and noisy, so every figure is a median over repeats.

Usage::

    python -m fog_gym.experiments.bench.env                  # 20 timed frames per configuration, town "highway"
    python -m fog_gym.experiments.bench.env --quick          # smoke run (3 frames, 3 profiled steps)
    python -m fog_gym.experiments.bench.env --town merge --repeats 50 --json out/bench_env.json
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from tqdm import tqdm

from fog_gym.experiments.bench.common import (
    CHANNEL_LABELS, WARMUP_STEPS, EpisodeKeeper, add_common_arguments, counts_summary, finish_meta, fmt_ms,
    idle_action, markdown_table, repeats_of, run_meta, sensor_tick, summarize, timed, write_json,
)  # fmt: skip
from fog_gym.world.towns import TOWNS

RESET_REPEATS = 3
PROFILE_STEPS = 10
DENSE_VEHICLES = 50

RIGS: dict[str, dict[str, Any]] = {
    # key: label, FogDriveEnv kwargs
    # (the point sensors of RigConfig.fogdrive() stay in both; bench_rig appends them to the label)
    "full": {"label": "full rig: 4 × 1280×960", "kwargs": {}},  # rig=None → RigConfig.fogdrive()
    "rl": {"label": "RL rig: 1 × 128×128", "kwargs": {"resolution": (128, 128), "cameras": ["CAM_FRONT"]}},
}


# -- FogDrive-v0 stages --------------------------------------------------------------------------------


def build_scene(env: Any) -> tuple[Any, dict[str, float]]:
    """``env.build_scene()`` (what ``step`` does before it renders), with its sub-stages timed separately."""
    from fog_gym.world.scene import vehicle_primitives
    from fog_gym.world.fleet import EGO_ID

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
    from fog_gym.sensors.rig import RigConfig
    from fog_gym.sensors import CameraRig

    return {c.name: CameraRig(RigConfig((c,)), far=env.config.far_distance) for c in env.config.rig.cameras}


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
        static.append(timed(env.build_static_world, np.random.default_rng(0))[1])  # what reset() builds
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
    rng = np.random.default_rng(0)  # the bench's own draws: the env's sensor stream is left to env.step
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
    out["counts"] = counts_summary(counts)
    out["resets"] = keep.resets
    return out


def point_sensor_label(env: Any) -> str:
    chans = env.point_sensors.channels
    return " + " + ", ".join(CHANNEL_LABELS.get(c, c) for c in chans) if chans else " (no point sensors)"


def measure_env_step(env: Any, action: Any, bare: Any, repeats: int, desc: str) -> tuple[dict, dict]:
    """Wall time of ``env.step(action)``, alternating with a bare highway-env step of the same scenario.

    ``env.step`` covers the traffic, the scene, every camera, the point sensors and the observation dict. Both envs
    start from the same traffic, and each timed ``env.step`` is followed by one timed ``bare.step``. The two
    series therefore see the same machine load, and their ratio holds up when the load drifts.
    """
    from fog_gym.envs.fogdrive import FogDriveEnv

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
    from fog_gym.envs.fogdrive import FogDriveEnv

    env, ms_init = timed(FogDriveEnv, town=town, **RIGS[rig_key]["kwargs"])
    label = RIGS[rig_key]["label"] + point_sensor_label(env)
    solos = solo_rigs(env)
    action = env.idle_action
    warm_up(env, solos, action)
    result: dict[str, Any] = {
        "label": label, "cameras": list(env.camera_names), "point_sensors": list(env.point_sensors.channels),
        "construct": summarize([ms_init]),
    }  # fmt: skip
    result["reset"], result["static_build"] = measure_reset(env, RESET_REPEATS, f"{rig_key}: reset")
    result["stages"] = measure_stages(env, solos, action, repeats, f"{rig_key}: stages")
    bare = bare_highway_env(town)
    result["env_step"], result["bare_step"] = measure_env_step(env, action, bare, repeats, f"{rig_key}: env.step")
    bare.close()
    env.close()
    return result


# -- bare highway-env ----------------------------------------------------------------------------------


def bare_highway_env(town: str, **overrides: Any) -> Any:
    """The town's highway-env scenario with fog-gym's config and frequencies (``fog_gym.world.towns.highway_env_config``),
    with the observation kept."""
    import highway_env.envs as hw_envs

    from fog_gym.envs.config import FogDriveConfig
    from fog_gym.world.towns import TOWN_SPECS, highway_env_config

    defaults = FogDriveConfig()
    config = highway_env_config(town, defaults.simulation_frequency, defaults.keyframe_frequency, overrides)
    return getattr(hw_envs, TOWN_SPECS[town].env_class)(config=config)


def measure_bare(bare_env: Any, repeats: int, desc: str, seed: int = 0) -> dict[str, Any]:
    """``bare_env.step(idle)`` wall time (observation included), and ``observe()`` timed alone after each step."""
    action = idle_action(bare_env.action_space)
    bare_env.reset(seed=seed)
    for _ in range(WARMUP_STEPS):
        bare_env.step(action)
    steps, observe, resets, n_vehicles = [], [], 0, []
    for _ in tqdm(range(repeats), desc=desc, unit="step", leave=False):
        (_, _, terminated, truncated, _), ms = timed(bare_env.step, action)
        steps.append(ms)
        observe.append(timed(bare_env.observation_type.observe)[1])
        n_vehicles.append(len(bare_env.road.vehicles))
        if terminated or truncated:
            resets += 1
            bare_env.reset(seed=resets)
    return {
        "step": summarize(steps), "observe": summarize(observe), "resets": resets,
        "vehicles": float(np.median(n_vehicles)),
        "substeps": int(bare_env.config["simulation_frequency"] // bare_env.config["policy_frequency"]),
    }  # fmt: skip


def profile_bare(bare_env: Any, steps: int) -> dict[str, Any]:
    """Run cProfile over ``steps`` highway-env steps. Return the share of profiled time in the O(N²) helpers."""
    action = idle_action(bare_env.action_space)
    bare_env.reset(seed=0)
    bare_env.step(action)
    prof = cProfile.Profile()
    resets = 0
    for _ in tqdm(range(steps), desc="profile", unit="step", leave=False):
        prof.enable()
        _, _, terminated, truncated, _ = bare_env.step(action)
        prof.disable()
        if terminated or truncated:  # the reset is not profiled
            resets += 1
            bare_env.reset(seed=resets)
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
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.world.towns import TOWN_SPECS, apply_idm_profile

    out: dict[str, Any] = {}
    configs = {
        # the town as FogDrive-v0 runs it, from the same initial traffic as FogDriveEnv.reset(seed=0)
        "town": (f"{town} ({TOWN_SPECS[town].env_class}, fog-gym config)", town, {}, FogDriveEnv.episode_seed_for(0)),
        # the highway town with more vehicles: 1 ego + 50 others
        "dense": (f"highway, vehicles_count={DENSE_VEHICLES}", "highway", {"vehicles_count": DENSE_VEHICLES}, 0),
    }
    for key, (label, t, overrides, seed) in configs.items():
        apply_idm_profile(t)  # the last world stepped may have left another town's IDM constants
        bare_env = bare_highway_env(t, **overrides)
        res = measure_bare(bare_env, repeats, f"bare {key}: step", seed)
        res["profile"] = profile_bare(bare_env, profile_steps)
        res["label"] = label
        res["config"] = {k: v for k, v in bare_env.config.items() if isinstance(v, (int, float, str, bool))}
        bare_env.close()
        out[key] = res
    return out


# -- RL preset ------------------------------------------------------------------------------------------


def bench_rl(repeats: int) -> dict[str, Any]:
    """``FogDriveRL-v0`` (dense fog) steps/s — one env, and 2 async subprocess envs — next to bare highway-env of
    the same scenario and frequencies (20 Hz sim, 5 Hz policy, 20 vehicles, 3 lanes), and the share of the step
    spent on sensors + fog + observation shaping."""
    import gymnasium as gym

    import fog_gym  # noqa: F401
    from fog_gym.envs.presets import RL_TRAFFIC

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
    bare_env = bare_highway_env("highway", **RL_TRAFFIC, policy_frequency=5)
    bare_rate = rate(bare_env)
    bare_vec = gym.vector.AsyncVectorEnv([lambda: bare_highway_env("highway", **RL_TRAFFIC, policy_frequency=5)] * 2)
    bare_vec_rate = rate(bare_vec, 2)
    bare_vec.close()
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


# -- report --------------------------------------------------------------------------------------------


def camera_keys(rig_result: dict[str, Any]) -> list[str]:
    return [f"camera:{n}" for n in rig_result["cameras"]]


def sum_medians(rig_result: dict[str, Any], keys: Any) -> float:
    return sum(rig_result["stages"][k]["median"] for k in keys)


STEP_STAGES = ("traffic_step", "scene_build", "cameras_batched", "point_sensors")


def render_stages(results: dict[str, Any]) -> str:
    """The header, the per-stage table of each rig and the scene sizes."""
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
        row("  static world build alone (`build_static_world`)", lambda r: fmt_ms(r["static_build"])),
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

    return "\n".join(out)


def render_baselines(results: dict[str, Any]) -> str:
    """The bare highway-env table and its cProfile shares."""
    meta, base = results["meta"], results["baseline"]
    out = [f"## Bare highway-env (observation included): ms, median (p25–p75), {meta['repeats']} steps", ""]
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


def bench_all(town: str, repeats: int, profile_steps: int) -> dict[str, Any]:
    """Both rigs, the RL preset and the bare baselines."""
    rigs = {key: bench_rig(town, key, repeats) for key in RIGS}
    rl = bench_rl(repeats)
    baseline = bench_baselines(town, repeats, profile_steps)
    return {"rigs": rigs, "rl": rl, "baseline": baseline}


def build_parser(prog: str = "python -m fog_gym.experiments.bench.env") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        description="Per-stage milliseconds of FogDrive-v0 (traffic step, scene build, cameras batched and alone, "
        "point sensors, full env.step) for the full 4×1280×960 rig and a 1×128×128 RL rig (both with LiDAR, "
        "semantic LiDAR and radar), against a bare highway-env step; bare highway-env profiled; FogDriveRL-v0 "
        "steps/s. It prints Markdown tables and asserts nothing.",
    )
    add_common_arguments(parser)
    parser.add_argument("--town", choices=TOWNS, default="highway", help="fog-gym town (default highway)")
    return parser


def main(argv: list[str] | None = None, prog: str = "python -m fog_gym.experiments.bench.env") -> int:
    args = build_parser(prog).parse_args(argv)
    repeats = repeats_of(args)
    profile_steps = 3 if args.quick else PROFILE_STEPS
    meta = run_meta(town=args.town, repeats=repeats, quick=args.quick, profile_steps=profile_steps)
    t0 = time.perf_counter()
    results = {"meta": meta, **bench_all(args.town, repeats, profile_steps)}
    finish_meta(meta, t0)
    print(render_stages(results))
    print("\n" + render_baselines(results))
    print("\n" + "\n".join(render_rl(results["rl"])))
    write_json(args.json, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
