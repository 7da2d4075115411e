"""What the world of meshes costs against the box world, measured in one run (``python -m
fog_gym.experiments.bench.geometry``; part of ``fog-gym bench``).

The same seeds run with ``geometry="boxes"`` (vehicles as a body and a cabin box, props as boxes: the renderer of the
previous release, which still draws box scenes bit for bit) and ``geometry="meshes"`` (procedural bodies, shaped
scenery, sun shadows):

* the full FogDrive rig's ``env.step`` by day and by night (paired fog: clean + light, moderate, dense);
* the point sensors alone (LiDAR, semantic LiDAR, radar) on the day scene;
* the pixel RL vector env (``FogDriveRL-v0``, 8 worlds, random actions) in steps per second;
* the memory an env allocates building and stepping its first frame (traced, peak).

Targets (issue "a world of shapes"): day ≤ 1.3×, night ≤ 1.5×, point sensors ≤ 2×, RL steps/s ≥ 0.75×, memory ≤ 1.5×.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc
from typing import Any

import numpy as np
from tqdm import tqdm

from fog_gym.experiments.bench.common import (add_common_arguments, finish_meta, markdown_table, meta_line, repeats_of,
                                              run_meta, summarize, write_json)  # fmt: skip

GEOMETRIES = ("boxes", "meshes")
TARGETS = {"day step": 1.3, "night step": 1.5, "point sensors": 2.0, "RL vector steps/s": 0.75, "memory": 1.5}


def _env(geometry: str, night: bool) -> Any:
    import gymnasium as gym

    import fog_gym  # noqa: F401

    return gym.make("FogDrive-v0", geometry=geometry, time_of_day="night" if night else "day",
                    fog=["light", "moderate", "dense"])  # fmt: skip


def bench_steps(geometry: str, night: bool, repeats: int, seed: int = 5) -> dict[str, Any]:
    env = _env(geometry, night)
    env.reset(seed=seed)
    for _ in range(2):
        env.step(1)
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        _, _, term, trunc, _ = env.step(1)
        samples.append((time.perf_counter() - t0) * 1e3)
        if term or trunc:
            env.reset(seed=seed)
    env.close()
    return summarize(samples)


def bench_point_sensors(geometry: str, repeats: int, seed: int = 5) -> dict[str, Any]:
    env = _env(geometry, False)
    env.reset(seed=seed)
    base = env.unwrapped
    prims = base.cameras.primitives(base.scene, in_view=False)
    rng = np.random.default_rng(0)
    base.point_sensors.measure(base.scene, prims, rng, 0)
    samples = []
    for k in range(repeats):
        t0 = time.perf_counter()
        base.point_sensors.measure(base.scene, prims, rng, k)
        samples.append((time.perf_counter() - t0) * 1e3)
    env.close()
    return summarize(samples)


def bench_rl_vector(geometry: str, steps: int, num_envs: int = 8) -> dict[str, Any]:
    import gymnasium as gym

    import fog_gym  # noqa: F401
    from fog_gym.envs.vector import FogDriveVectorEnv

    envs = FogDriveVectorEnv("FogDriveRL-v0", num_envs, fog="dense", geometry=geometry)
    envs.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(3):
        envs.step(rng.integers(0, 5, num_envs))
    t0 = time.perf_counter()
    for _ in range(steps):
        envs.step(rng.integers(0, 5, num_envs))
    seconds = time.perf_counter() - t0
    envs.close()
    assert gym is not None
    return {"steps_per_s": steps * num_envs / seconds, "num_envs": num_envs, "steps": steps}


def bench_memory(geometry: str, seed: int = 5) -> dict[str, Any]:
    tracemalloc.start()
    env = _env(geometry, False)
    env.reset(seed=seed)
    env.step(1)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    env.close()
    return {"peak_mb": peak / 2**20}


def bench_geometry(repeats: int, rl_steps: int = 60) -> dict[str, Any]:
    out: dict[str, dict[str, Any]] = {g: {} for g in GEOMETRIES}
    jobs = [(g, name) for name in ("day step", "night step", "point sensors", "RL vector steps/s", "memory")
            for g in GEOMETRIES]  # fmt: skip
    for g, name in tqdm(jobs, desc="geometry bench", unit="measure"):
        if name == "day step":
            out[g][name] = bench_steps(g, False, repeats)
        elif name == "night step":
            out[g][name] = bench_steps(g, True, max(3, repeats // 4))
        elif name == "point sensors":
            out[g][name] = bench_point_sensors(g, repeats)
        elif name == "RL vector steps/s":
            out[g][name] = bench_rl_vector(g, rl_steps)
        else:
            out[g][name] = bench_memory(g)
    return out


def _value(stat: dict[str, Any]) -> float:
    return stat.get("median", stat.get("steps_per_s", stat.get("peak_mb", float("nan"))))


def render_geometry(res: dict[str, Any]) -> list[str]:
    rows = []
    for name, target in TARGETS.items():
        b, m = _value(res["boxes"][name]), _value(res["meshes"][name])
        ratio = m / b
        higher_better = name.endswith("steps/s")
        ok = ratio >= target if higher_better else ratio <= target
        unit = "steps/s" if higher_better else ("MB" if name == "memory" else "ms")
        rows.append([name, f"{b:.1f} {unit}", f"{m:.1f} {unit}", f"{ratio:.2f}×",
                     f"{'≥' if higher_better else '≤'} {target}× {'✓' if ok else '✗'}"])  # fmt: skip
    return ["### Meshes against boxes (same seeds, one run)", "",
            markdown_table(["measure", "boxes", "meshes", "meshes / boxes", "target"], rows)]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m fog_gym.experiments.bench.geometry", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    add_common_arguments(p)
    a = p.parse_args(argv)
    repeats = repeats_of(a)
    meta = run_meta(repeats=repeats, quick=a.quick)
    t0 = time.perf_counter()
    res = bench_geometry(repeats, 10 if a.quick else 60)
    finish_meta(meta, t0)
    print(meta_line(meta))
    print("\n".join(render_geometry(res)))
    write_json(a.json, {"meta": meta, "geometry": res})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
