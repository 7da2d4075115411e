"""What the world of meshes costs against the box world, measured in one run (``python -m
fog_gym.experiments.bench.geometry``; part of ``fog-gym bench``).

Boxes and meshes are timed in turn on envs built once each (a step, a sensor sweep or a chunk of RL steps of one,
then of the other), so drift on a shared machine falls on both alike. The same seeds run with ``geometry="boxes"``
(vehicles as a body and a cabin box, props as boxes: the renderer of the previous release, which still draws box
scenes bit for bit) and ``geometry="meshes"`` (procedural bodies, shaped scenery, sun shadows):

* the full FogDrive rig's ``env.step`` by day and by night (paired fog: clean + light, moderate, dense);
* the point sensors alone (LiDAR, semantic LiDAR, radar) on the day scene;
* the pixel RL vector env (``FogDriveRL-v0``, 8 worlds, random actions) in steps per second (the median of four
  chunks of 15 vector steps);
* the memory an env allocates building and stepping its first frame (traced, peak).

Targets (issue "a world of shapes"): day ≤ 1.3×, night ≤ 1.5×, point sensors ≤ 2×, RL steps/s ≥ 0.75×, memory ≤ 1.5×.
"""

from __future__ import annotations

import argparse
import time
import tracemalloc
from pathlib import Path
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


def _interleaved(make: Any, timed: Any, rounds: int) -> dict[str, list[float]]:
    """Build one subject per geometry with ``make(g)``, then ``rounds`` times time ``timed(subject)`` for boxes and
    meshes in turn, so drift on a shared machine falls on both alike; the samples per geometry."""
    subjects = {g: make(g) for g in GEOMETRIES}
    samples: dict[str, list[float]] = {g: [] for g in GEOMETRIES}
    for _ in range(rounds):
        for g in GEOMETRIES:
            samples[g].append(timed(subjects[g]))
    for env in subjects.values():
        env.close()
    return samples


def bench_steps(night: bool, repeats: int, seed: int = 5) -> dict[str, dict[str, Any]]:
    """The full rig's ``env.step`` (paired fog) for both geometries, a step of each in turn."""

    def make(g: str) -> Any:
        env = _env(g, night)
        env.reset(seed=seed)
        for _ in range(2):
            env.step(1)
        return env

    def timed(env: Any) -> float:
        t0 = time.perf_counter()
        _, _, term, trunc, _ = env.step(1)
        ms = (time.perf_counter() - t0) * 1e3
        if term or trunc:
            env.reset(seed=seed)
        return ms

    return {g: summarize(v) for g, v in _interleaved(make, timed, repeats).items()}


def bench_point_sensors(repeats: int, seed: int = 5) -> dict[str, dict[str, Any]]:
    """LiDAR, semantic LiDAR and radar on the day scene, for both geometries in turn."""
    rng = np.random.default_rng(0)

    def make(g: str) -> Any:
        env = _env(g, False)
        env.reset(seed=seed)
        base = env.unwrapped
        env.prims = base.cameras.primitives(base.scene, in_view=False)  # type: ignore[attr-defined]
        base.point_sensors.measure(base.scene, env.prims, rng, 0)  # type: ignore[attr-defined]
        return env

    def timed(env: Any) -> float:
        base = env.unwrapped
        t0 = time.perf_counter()
        base.point_sensors.measure(base.scene, env.prims, rng, 1)
        return (time.perf_counter() - t0) * 1e3

    return {g: summarize(v) for g, v in _interleaved(make, timed, repeats).items()}


def bench_rl_vector(steps: int, num_envs: int = 8, rounds: int = 4) -> dict[str, dict[str, Any]]:
    """The pixel RL vector env (random actions, dense fog) in steps per second: ``rounds`` chunks of ``steps``
    vector steps per geometry in turn; the median chunk."""
    from fog_gym.envs.vector import FogDriveVectorEnv

    rng = np.random.default_rng(0)

    def make(g: str) -> Any:
        envs = FogDriveVectorEnv("FogDriveRL-v0", num_envs, fog="dense", geometry=g)
        envs.reset(seed=0)
        for _ in range(3):
            envs.step(rng.integers(0, 5, num_envs))
        return envs

    def timed(envs: Any) -> float:
        t0 = time.perf_counter()
        for _ in range(steps):
            envs.step(rng.integers(0, 5, num_envs))
        return steps * num_envs / (time.perf_counter() - t0)

    out = {}
    for g, rates in _interleaved(make, timed, rounds).items():
        out[g] = {"steps_per_s": float(np.median(rates)), "chunks": [round(r, 1) for r in rates],
                  "num_envs": num_envs, "steps": steps}  # fmt: skip
    return out


def bench_memory(geometry: str, seed: int = 5) -> dict[str, Any]:
    tracemalloc.start()
    env = _env(geometry, False)
    env.reset(seed=seed)
    env.step(1)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    env.close()
    return {"peak_mb": peak / 2**20}


def bench_geometry(repeats: int, rl_steps: int = 15) -> dict[str, Any]:
    out: dict[str, dict[str, Any]] = {g: {} for g in GEOMETRIES}
    jobs = {
        "day step": lambda: bench_steps(False, repeats),
        "night step": lambda: bench_steps(True, max(3, repeats // 4)),
        "point sensors": lambda: bench_point_sensors(repeats),
        "RL vector steps/s": lambda: bench_rl_vector(rl_steps),
        "memory": lambda: {g: bench_memory(g) for g in GEOMETRIES},
    }
    for name, job in tqdm(jobs.items(), desc="geometry bench (boxes and meshes in turn)", unit="measure"):
        for g, stat in job().items():
            out[g][name] = stat
    return out


#: What one subprocess of the previous-release comparison times (the API both releases share): the full rig's
#: day step (paired fog) and the pixel RL vector env's steps per second.
_TIMER = """
import json, sys, time
import numpy as np, gymnasium as gym, fog_gym
from fog_gym.envs.vector import FogDriveVectorEnv
kw, repeats, steps = json.loads(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
env = gym.make("FogDrive-v0", fog=["light", "moderate", "dense"], **kw)
env.reset(seed=5)
for _ in range(2):
    env.step(1)
day = []
for _ in range(repeats):
    t0 = time.perf_counter()
    env.step(1)
    day.append((time.perf_counter() - t0) * 1e3)
env.close()
envs = FogDriveVectorEnv("FogDriveRL-v0", 8, fog="dense", **kw)
envs.reset(seed=0)
rng = np.random.default_rng(0)
for _ in range(3):
    envs.step(rng.integers(0, 5, 8))
t0 = time.perf_counter()
for _ in range(steps):
    envs.step(rng.integers(0, 5, 8))
rate = steps * 8 / (time.perf_counter() - t0)
print("RESULT " + json.dumps({"day_ms": float(np.median(day)), "rl_steps_per_s": rate}))
"""


def _checkout(previous: str) -> str:
    """``previous`` resolved, after refusing a folder that holds no fog-gym checkout."""
    if not (Path(previous) / "fog_gym" / "__init__.py").is_file():
        raise ValueError(f"--previous must be a checkout of fog-gym (a folder with fog_gym/), got {previous!r}")
    return str(Path(previous).resolve())


def bench_previous(previous: str, repeats: int, steps: int, rounds: int = 5) -> dict[str, Any]:
    """The previous release's box world (a checkout at ``previous``) against this tree's meshes, each in its own
    processes, ``rounds`` times in turn: the medians of the day step [ms] and the RL vector env's steps/s, and the
    median over rounds of each round's ratio (``ratios``)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    here = str(Path(__file__).resolve().parents[3])
    prev = _checkout(previous)
    sides = {"previous boxes": (prev, {}), "meshes": (here, {"geometry": "meshes"})}
    runs: dict[str, list[dict]] = {k: [] for k in sides}
    for _ in tqdm(range(rounds), desc="previous release against meshes", unit="round"):
        for name, (tree, kw) in sides.items():
            env = {**os.environ, "PYTHONPATH": tree}
            out = subprocess.run([sys.executable, "-c", _TIMER, json.dumps(kw), str(repeats), str(steps)], cwd=tree,
                                 env=env, capture_output=True, text=True, check=True).stdout  # fmt: skip
            runs[name].append(json.loads(out.split("RESULT ", 1)[1]))
    out: dict[str, Any] = {name: {"day_ms": float(np.median([r["day_ms"] for r in rs])),
                                  "rl_steps_per_s": float(np.median([r["rl_steps_per_s"] for r in rs])), "runs": rs}
                           for name, rs in runs.items()}  # fmt: skip
    # each round's ratio (its two processes ran one after the other), then the median: a slow phase of the machine
    # moves both sides of a round
    b, m = runs["previous boxes"], runs["meshes"]
    out["ratios"] = {"day step": float(np.median([y["day_ms"] / x["day_ms"] for x, y in zip(b, m)])),
                     "RL vector steps/s": float(np.median([y["rl_steps_per_s"] / x["rl_steps_per_s"]
                                                          for x, y in zip(b, m)]))}  # fmt: skip
    return out


def render_previous(res: dict[str, Any]) -> list[str]:
    b, m = res["previous boxes"], res["meshes"]
    day, rl = res["ratios"]["day step"], res["ratios"]["RL vector steps/s"]
    rows = [["day step", f"{b['day_ms']:.1f} ms", f"{m['day_ms']:.1f} ms", f"{day:.2f}×",
             f"≤ {TARGETS['day step']}× {'✓' if day <= TARGETS['day step'] else '✗'}"],
            ["RL vector steps/s", f"{b['rl_steps_per_s']:.1f} steps/s", f"{m['rl_steps_per_s']:.1f} steps/s",
             f"{rl:.2f}×", f"≥ {TARGETS['RL vector steps/s']}× {'✓' if rl >= TARGETS['RL vector steps/s'] else '✗'}"]]
    return ["### Meshes against the previous release's box renderer (own processes, in turn)", "",
            markdown_table(["measure", "previous release (boxes)", "meshes", "meshes / previous (median of rounds)",
                            "target"], rows)]  # fmt: skip


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
    p.add_argument("--previous", metavar="DIR", help="also compare against the previous release's box renderer: a "
                   "checkout of it (e.g. `git worktree add ../fog-gym-prev <tag>`), timed in its own processes")
    a = p.parse_args(argv)
    if a.previous is not None:
        try:
            _checkout(a.previous)
        except ValueError as e:
            p.error(str(e))
    repeats = repeats_of(a)
    meta = run_meta(repeats=repeats, quick=a.quick)
    t0 = time.perf_counter()
    res = bench_geometry(repeats, 5 if a.quick else 15)
    prev = None if a.previous is None else bench_previous(a.previous, repeats, 5 if a.quick else 30)
    finish_meta(meta, t0)
    print(meta_line(meta))
    print("\n".join(render_geometry(res)))
    if prev is not None:
        print("\n" + "\n".join(render_previous(prev)))
    write_json(a.json, {"meta": meta, "geometry": res, "previous": prev})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
