"""Speed: the vector envs, sums of fog fields and scaling over cores, each against another install in one run.

* **vector envs** (16 worlds): ``FogDriveRLHazard-v0`` with perceived objects, ``FogDriveRLObjects-v0``, and
  ``FogDriveRL-v0`` with pixels in dense fog on the mesh world — steps per second (world-steps);
* **sums of fog fields**: a ``FogDrive-v0`` step (the RL preset's rig: one 64 × 64 camera and a 32-channel LiDAR)
  fogged by ``HeightFog + FogBank`` and by two banks, against the same step in homogeneous fog; the LiDAR fog of
  100 k points likewise;
* **scaling**: ``fog-gym generate`` with 1 … N workers and the sharded vector env (``FogDriveRLHazard-v0``, 16 worlds,
  objects and pixels) with 1 … N shards (N: this machine's cores, powers of two).

With ``--previous DIR`` (a checkout of another release, e.g. ``git worktree add ../fog-gym-prev 3c4c6c8``) each
vector-env and fog figure runs in child processes of both installs in turn (``PYTHONPATH`` picks the tree; a warm-up
round first), ``--rounds`` times, and the ratio is the median of the per-round ratios. The sums' cost over homogeneous
fog is measured in this tree alone, each sum in one child that alternates it with homogeneous fog (:data:`RATIOS`: the
median of the per-block ratios, then of the children). Prints Markdown; asserts no timing.

Usage::

    python -m fog_gym.experiments.bench.speed --previous ../fog-gym-prev
    python -m fog_gym.experiments.bench.speed --quick --no-scaling
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.bench.common import finish_meta, markdown_table, meta_line, run_meta, write_json

#: The issue's targets: this tree's figure over the previous release's (vector envs: steps/s, higher is better) and
#: the cost of a sum of fields over homogeneous fog (lower is better).
TARGETS = {"objects (FogDriveRLHazard-v0)": 1.8, "objects (FogDriveRLObjects-v0)": 1.8, "pixels (FogDriveRL-v0)": 1.5,
           "step, HeightFog + FogBank": 1.5, "step, two banks": 1.5, "LiDAR fog, HeightFog + FogBank": 2.0,
           "LiDAR fog, two banks": 2.0}  # fmt: skip

#: The child's program: one figure, printed as JSON (it uses only what both installs have).
CHILD = r"""
import json, sys, time
import numpy as np
import gymnasium as gym
import fog_gym
what, steps = sys.argv[1], int(sys.argv[2])
def rate(envs, n):
    envs.reset(seed=0)
    a = np.ones(n, np.int64)
    for _ in range(5):
        envs.step(a)
    t = time.perf_counter()
    for _ in range(steps):
        envs.step(a)
    return steps * n / (time.perf_counter() - t)
n = 16
if what == "hazard-objects":
    out = rate(gym.make_vec("FogDriveRLHazard-v0", num_envs=n, vectorization_mode="vector_entry_point",
                            observation="objects", fog="dense"), n)
elif what == "objects":
    out = rate(gym.make_vec("FogDriveRLObjects-v0", num_envs=n, vectorization_mode="vector_entry_point", fog="dense"), n)
elif what == "pixels":
    out = rate(gym.make_vec("FogDriveRL-v0", num_envs=n, vectorization_mode="vector_entry_point", fog="dense",
                            geometry="meshes"), n)
else:
    from fog_gym.fog.fields import FogBank, HeightFog
    fields = {"homogeneous": "dense", "height+bank": HeightFog(50.0, 4.0) + FogBank(50.0, 40.0, 80.0),
              "two banks": FogBank(50.0, 20.0, 40.0) + FogBank(80.0, 90.0, 60.0)}
    kind, field = what.split(":")
    def unit(kind, field):  # one step of FogDriveRL-v0 in the field, or the LiDAR fog of 100 k points in it
        if kind.endswith("step"):
            env = gym.make("FogDriveRL-v0", fog=fields[field])
            env.reset(seed=0)
            for _ in range(3):
                env.step(1)
            return lambda: env.step(1)
        from fog_gym.fog.depth import field_pose
        from fog_gym.fog.lidar import fog_lidar
        from fog_gym.fog.lidar_field import fog_lidar_field
        from fog_gym.fog.physics import parse_fog
        rng = np.random.default_rng(0)
        r = rng.uniform(2.0, 120.0, 100_000)
        az = rng.uniform(-np.pi, np.pi, r.size)
        el = rng.choice(np.radians(np.linspace(-20.0, 5.0, 64)), r.size)
        pts = np.c_[r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az), r * np.sin(el),
                    rng.uniform(0.05, 1.0, r.size)].astype(np.float32)
        pose = field_pose(np.r_[np.c_[np.eye(3), [0.0, 0.0, 2.0]], [[0, 0, 0, 1]]], (0.0, 0.0, 0.0))
        if field == "homogeneous":
            call = lambda: fog_lidar(pts, parse_fog("dense"), rng)
        else:
            call = lambda: fog_lidar_field(pts, fields[field], rng, pose)
        call()
        return call
    def block(call, k):
        t = time.perf_counter()
        for _ in range(k):
            call()
        return (time.perf_counter() - t) / k
    if kind.startswith("ratio-"):  # the field against homogeneous fog in this process, alternating: median of ratios
        base, other = unit(kind, "homogeneous"), unit(kind, field)
        k = 5 if kind.endswith("step") else 1
        ratios = []
        for i in range(steps):  # each round in turn starts with the other
            if i % 2:
                t_base = block(base, k)
                t_other = block(other, k)
            else:
                t_other = block(other, k)
                t_base = block(base, k)
            ratios.append(t_other / t_base)
        out = float(np.median(ratios))
    elif kind == "step":  # the mean step
        out = block(unit(kind, field), steps) * 1000.0
    else:  # the median call
        call = unit(kind, field)
        out = float(np.median([block(call, 1) for _ in range(steps)])) * 1000.0
print(json.dumps({"value": out}))
"""

#: What each figure runs in the child, its unit, and whether higher is better.
FIGURES = {
    "objects (FogDriveRLHazard-v0)": ("hazard-objects", 300, "steps/s"),
    "objects (FogDriveRLObjects-v0)": ("objects", 300, "steps/s"),
    "pixels (FogDriveRL-v0)": ("pixels", 40, "steps/s"),
    "step, homogeneous": ("step:homogeneous", 60, "ms"),
    "step, HeightFog + FogBank": ("step:height+bank", 60, "ms"),
    "step, two banks": ("step:two banks", 60, "ms"),
    "LiDAR fog, homogeneous": ("lidar:homogeneous", 10, "ms"),
    "LiDAR fog, HeightFog + FogBank": ("lidar:height+bank", 10, "ms"),
    "LiDAR fog, two banks": ("lidar:two banks", 10, "ms"),
}


#: The sums' cost over homogeneous fog in this tree, each measured in one child alternating the two (blocks of five
#: steps, or single LiDAR fog calls): the median of the per-block ratios, a figure the machine's drift between
#: processes does not move (the ratio of two figures measured minutes apart did: 1.49× in one run, 2.17× in another).
RATIOS = {
    "step, HeightFog + FogBank": ("ratio-step:height+bank", 24),
    "step, two banks": ("ratio-step:two banks", 24),
    "LiDAR fog, HeightFog + FogBank": ("ratio-lidar:height+bank", 20),
    "LiDAR fog, two banks": ("ratio-lidar:two banks", 20),
}


def child(tree: str, what: str, steps: int) -> float:
    """One figure measured by a child process of the install at ``tree`` (working folder outside it)."""
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "PYTHONPATH": tree}
        out = subprocess.run([sys.executable, "-c", CHILD, what, str(steps)], cwd=tmp, env=env, capture_output=True,
                             text=True, check=True).stdout  # fmt: skip
    return float(json.loads(out.strip().splitlines()[-1])["value"])


def bench_figures(trees: dict[str, str], rounds: int, quick: bool) -> dict[str, Any]:
    """Every figure of :data:`FIGURES` for each install in ``trees``, in turn, ``rounds`` times after a warm-up."""
    from tqdm import tqdm

    res: dict[str, Any] = {}
    for name, (what, steps, unit) in tqdm(FIGURES.items(), desc="speed figures", unit="figure", file=sys.stderr):
        steps = max(2, steps // 5) if quick else steps
        runs: dict[str, list[float]] = {k: [] for k in trees}
        for k in range(rounds + 1):
            for side, tree in trees.items():
                v = child(tree, what, max(2, steps // 4) if k == 0 else steps)
                if k:
                    runs[side].append(v)
        res[name] = {"unit": unit, "runs": runs, "median": {s: float(np.median(v)) for s, v in runs.items()}}
        if len(trees) == 2:
            a, b = runs["this tree"], runs["previous"]
            per_round = [x / y if unit == "steps/s" else y / x for x, y in zip(a, b)]
            res[name]["ratio"] = float(np.median(per_round))  # this tree's speed-up
    return res


def installs(previous: str | None) -> dict[str, str]:
    """The installs the figures run in: this tree and, when ``previous`` is given, that checkout (a ``ValueError``
    when it holds no fog-gym)."""
    from fog_gym.experiments.bench.geometry import _checkout

    trees = {"this tree": str(Path(__file__).resolve().parents[3])}
    if previous is not None:
        trees["previous"] = _checkout(previous)
    return trees


def core_counts() -> list[int]:
    """The core counts of the scaling curve: the powers of two up to this machine's cores."""
    return [k for k in (1, 2, 4, 8, 16, 32, 64) if k <= (os.cpu_count() or 1)]


def bench_ratios(tree: str, rounds: int, quick: bool) -> dict[str, Any]:
    """Every ratio of :data:`RATIOS` in ``tree``, ``rounds`` child processes each: the per-child medians and their
    median."""
    from tqdm import tqdm

    res: dict[str, Any] = {}
    for name, (what, blocks) in tqdm(RATIOS.items(), desc="sums over homogeneous", unit="figure", file=sys.stderr):
        runs = [child(tree, what, max(4, blocks // 4) if quick else blocks) for _ in range(rounds)]
        res[name] = {"runs": runs, "ratio": float(np.median(runs))}
    return res


def bench_scaling(cores: list[int], quick: bool) -> dict[str, Any]:
    """``fog-gym generate`` (the same max(4, N) scenes × 2 s, 640 × 480, full rig, after a warm-up run) with 1 … N
    workers, and the sharded vector env (16 worlds; perceived objects and pixels) with 1 … N shards: samples/s,
    steps/s."""
    import gymnasium as gym

    from fog_gym.generate import generate, plan_scenes

    out: dict[str, Any] = {"generate": {}, "sharded objects": {}, "sharded pixels": {}}
    # as many scenes as the most workers (at least 4): generate parallelises over scenes
    plan = plan_scenes(max(4, max(cores) + max(cores) % 2), towns=("merge",), resolution=(640, 480),
                       seconds=1.0 if quick else 2.0)  # fmt: skip
    samples = sum(s.expected_samples for s in plan)
    with tempfile.TemporaryDirectory() as tmp:
        generate(Path(tmp) / "warm", plan[:2], workers=max(cores), progress=False)  # kernels compiled and cached
        for k in cores:
            t = time.perf_counter()
            generate(Path(tmp) / f"w{k}", plan, workers=k, progress=False)
            wall = time.perf_counter() - t
            out["generate"][k] = {"scenes": len(plan), "seconds": wall, "samples_per_s": samples / wall}
    for key, kwargs, steps in (("sharded objects", {"observation": "objects"}, 300),
                               ("sharded pixels", {"geometry": "meshes"}, 30)):  # fmt: skip
        for k in cores:
            envs = gym.make_vec("FogDriveRLHazard-v0", num_envs=16, vectorization_mode="vector_entry_point",
                                fog="dense", shards=k, **kwargs)  # fmt: skip
            try:
                envs.reset(seed=0)
                a = np.ones(16, np.int64)
                for _ in range(5):
                    envs.step(a)
                n = max(5, steps // 6) if quick else steps
                t = time.perf_counter()
                for _ in range(n):
                    envs.step(a)
                out[key][k] = {"steps_per_s": n * 16 / (time.perf_counter() - t)}
            finally:
                envs.close()
    return out


def render_figures(res: dict[str, Any], rounds: int, ratios: dict[str, Any] | None = None) -> list[str]:
    two = any("ratio" in r for r in res.values())
    rows = []
    for name, r in res.items():
        m = r["median"]
        row = [name, f"{m['this tree']:.1f} {r['unit']}"]
        if two:
            row.append(f"{m['previous']:.1f} {r['unit']}")
            row.append(f"**{r['ratio']:.2f}×**" if "ratio" in r else "")
            target = TARGETS.get(name)
            row.append("" if target is None or not name.startswith(("objects", "pixels")) else
                       f"≥ {target:g}×: {'met' if r['ratio'] >= target else 'not met'}")  # fmt: skip
        rows.append(row)
    # the sums' cost over homogeneous fog, in this tree: alternating in one process (ratios), else the figures' medians
    for kind in ("step", "LiDAR fog"):
        base = res.get(f"{kind}, homogeneous")
        for field in ("HeightFog + FogBank", "two banks"):
            name = f"{kind}, {field}"
            r = res.get(name)
            if name in (ratios or {}):
                ratio, how = ratios[name]["ratio"], "alternating in one process"
            elif base and r:
                ratio, how = r["median"]["this tree"] / base["median"]["this tree"], "figures' medians"
            else:
                continue
            target = TARGETS[name]
            rows.append([f"{name} / homogeneous (this tree, {how})", f"**{ratio:.2f}×**"]
                        + ([""] * 2 if two else []) + [f"≤ {target:g}×: {'met' if ratio <= target else 'not met'}"])
    header = ["figure", "this tree"] + (["previous", "this / previous", "target"] if two else ["target"])
    if not two:  # the target column only on the ratio rows
        rows = [row + [""] if len(row) == 2 else row for row in rows]
    return [f"**Speed** ({rounds} rounds, child processes in turn; medians)", "", markdown_table(header, rows)]


def render_scaling(res: dict[str, Any]) -> list[str]:
    rows = []
    first = {key: res[key][min(res[key])] for key in res}
    for k in sorted(res["generate"]):
        row = [str(k)]
        for key, unit in (("generate", "samples_per_s"), ("sharded objects", "steps_per_s"), ("sharded pixels", "steps_per_s")):
            v = res[key][k][unit]
            row.append(f"{v:.1f} ({v / first[key][unit]:.2f}×)")
        rows.append(row)
    scenes = next(iter(res["generate"].values()))["scenes"]
    return ["**Scaling over cores**", "", markdown_table(
        ["cores", f"generate: samples/s ({scenes} scenes, 640 × 480, full rig)", "sharded vector env, objects: steps/s",
         "sharded vector env, pixels: steps/s"], rows)]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fog_gym.experiments.bench.speed", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    parser.add_argument("--previous", metavar="DIR", help="a checkout of another release to compare against")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of each figure per install (default 3)")
    parser.add_argument("--quick", action="store_true", help="smoke run: fewer steps, one round")
    parser.add_argument("--no-scaling", action="store_true", help="skip the scaling over cores")
    parser.add_argument("--no-figures", action="store_true", help="only the scaling over cores")
    parser.add_argument("--json", type=Path, default=None, metavar="PATH", help="also write every figure as JSON")
    args = parser.parse_args(argv)
    if args.rounds < 1:
        parser.error("--rounds must be >= 1")
    rounds = 1 if args.quick else args.rounds
    try:
        trees = installs(args.previous)
    except ValueError as e:
        parser.error(str(e))
    meta = run_meta(rounds=rounds, quick=args.quick, previous=args.previous)
    t0 = time.perf_counter()
    figures = None if args.no_figures else bench_figures(trees, rounds, args.quick)
    ratios = None if args.no_figures else bench_ratios(trees["this tree"], rounds, args.quick)
    scaling = None if args.no_scaling else bench_scaling(core_counts(), args.quick)
    finish_meta(meta, t0)
    print(meta_line(meta))
    if figures:
        print("\n".join(render_figures(figures, rounds, ratios)))
    if scaling:
        print("\n" + "\n".join(render_scaling(scaling)))
    write_json(args.json, {"meta": meta, "figures": figures, "ratios": ratios, "scaling": scaling})
    return 0


if __name__ == "__main__":
    sys.exit(main())
