#!/usr/bin/env python
"""Traffic core and parallel recorder against highway-env's own path and the serial writer.

Reports numbers only (Markdown on stdout, progress on stderr); never asserts a timing. Every figure is a
ratio of two paths measured in the same run, alternating step by step so both see the same machine load; each
speed-up is given from wall-clock time and from this process's CPU time per step (the steadier of the two on
a machine shared with other jobs).

1. **Traffic step vs vehicle count**: ``TrafficWorld.step`` (2 × 20 Hz sub-steps, highway-env's observation
   skipped) on the ``highway`` town with ``vehicles_count`` in ``--vehicles``, ``traffic="reference"`` and
   ``"fast"``; median ms and the speed-up. A log–log figure goes to ``--figure``.
2. **Plain highway-env**: ``gym.make("highway-v0")`` against ``fog_gym.accelerate(gym.make("highway-v0"))``,
   steps per second with highway-env's observation included.
3. **FogDriveRL-v0** steps per second, ``traffic="reference"`` against the default.
4. **cProfile** of the fast traffic step (50 vehicles, CPU-time clock): the top functions by own time, as shares.
5. **Recorder**: ms per full-rig paired sample (35 files) written serially (``workers=1``), with 2 threads and
   with one thread per core, against the serial PNG bound (the 24 images encoded one after another).
6. ``--identity STEPS``: the long identity check (every plain scenario and town, seeds 0–2), failing loudly.

Usage::

    python scripts/bench_traffic.py --quick
    python scripts/bench_traffic.py --repeats 20 --json out/traffic.json --figure out/traffic.png
    python scripts/bench_traffic.py --identity 300 --skip-speed
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import platform
import pstats
import sys
import tempfile
import time
from typing import Any

import numpy as np
from tqdm import tqdm


def _ms(fn: Any, *args: Any) -> tuple[Any, float]:
    t = time.perf_counter()
    out = fn(*args)
    return out, (time.perf_counter() - t) * 1e3


def _ms_cpu(fn: Any, *args: Any) -> tuple[Any, float, float]:
    """``fn(*args)``, its wall-clock ms and this process's CPU ms (robust to other jobs on a shared machine)."""
    c = time.process_time()
    t = time.perf_counter()
    out = fn(*args)
    return out, (time.perf_counter() - t) * 1e3, (time.process_time() - c) * 1e3


def bench_scaling(counts: list[int], repeats: int) -> dict[int, dict[str, float]]:
    from fog_gym.world.traffic_world import TrafficWorld

    out = {}
    for n in tqdm(counts, desc="vehicle counts", file=sys.stderr):
        worlds = {m: TrafficWorld("highway", traffic=m, highway_config={"vehicles_count": n}) for m in ("reference", "fast")}
        times: dict[str, list[float]] = {m: [] for m in worlds}
        cpu: dict[str, list[float]] = {m: [] for m in worlds}
        for w in worlds.values():
            w.reset(seed=0)
            w.step(1)
        for k in range(repeats):
            for m, w in worlds.items():
                (_, term, _), ms, cpu_ms = _ms_cpu(w.step, 1)
                times[m].append(ms)
                cpu[m].append(cpu_ms)
                if term:
                    w.reset(seed=k + 1)
        ref, fast = (float(np.median(times[m])) for m in ("reference", "fast"))
        ref_cpu, fast_cpu = (float(np.median(cpu[m])) for m in ("reference", "fast"))
        out[n] = {"reference_ms": ref, "fast_ms": fast, "speedup": ref / fast,
                  "reference_cpu_ms": ref_cpu, "fast_cpu_ms": fast_cpu, "speedup_cpu": ref_cpu / max(fast_cpu, 1e-9),
                  "vehicles": worlds["fast"].vehicle_count}  # fmt: skip
    return out


def bench_plain(repeats: int) -> dict[str, float]:
    import gymnasium as gym
    import highway_env  # noqa: F401

    from fog_gym.world.traffic import accelerate

    envs = {"reference": gym.make("highway-v0"), "fast": accelerate(gym.make("highway-v0"))}
    for e in envs.values():
        e.reset(seed=0)
    return _steps_per_second(envs, repeats, "highway-v0")


def _steps_per_second(envs: dict[str, Any], repeats: int, desc: str) -> dict[str, float]:
    """Alternate ``step`` between the paths; steps/s from median wall-clock and median CPU time per step."""
    times: dict[str, list[float]] = {m: [] for m in envs}
    cpu: dict[str, list[float]] = {m: [] for m in envs}
    for k in tqdm(range(repeats), desc=desc, file=sys.stderr):
        for m, e in envs.items():
            (_, _, term, trunc, _), ms, cpu_ms = _ms_cpu(e.step, 1)
            times[m].append(ms)
            cpu[m].append(cpu_ms)
            if term or trunc:
                e.reset(seed=k + 1)
    ref, fast = (1e3 / float(np.median(times[m])) for m in ("reference", "fast"))
    ref_cpu, fast_cpu = (float(np.median(cpu[m])) for m in ("reference", "fast"))
    return {"reference_sps": ref, "fast_sps": fast, "speedup": fast / ref,
            "speedup_cpu": ref_cpu / max(fast_cpu, 1e-9)}  # fmt: skip


def bench_rl(repeats: int) -> dict[str, float]:
    from fog_gym.envs.presets import make_fogdrive_rl

    envs = {m: make_fogdrive_rl(traffic=m) for m in ("reference", "fast")}
    for e in envs.values():
        e.reset(seed=0)
        e.step(1)
    out = _steps_per_second(envs, repeats, "FogDriveRL-v0")
    for e in envs.values():
        e.close()
    return out


def profile_fast(steps: int, top: int = 8) -> list[tuple[str, float]]:
    from fog_gym.world.traffic_world import TrafficWorld

    w = TrafficWorld("highway", traffic="fast", highway_config={"vehicles_count": 50})
    w.reset(seed=0)
    w.step(1)
    prof = cProfile.Profile(time.process_time)  # CPU time: other jobs' time slices land on no function
    for k in range(steps):
        prof.enable()
        _, term, _ = w.step(1)
        prof.disable()
        if term:
            w.reset(seed=k + 1)
    stats = pstats.Stats(prof)
    total = stats.total_tt
    rows = sorted(((f"{os.path.basename(f)}:{fn}", tt / total) for (f, _, fn), (_, _, tt, _, _) in stats.stats.items()),
                  key=lambda r: -r[1])  # fmt: skip
    return rows[:top]


def bench_recorder(repeats: int) -> dict[str, Any]:
    from fog_gym.dataset.writer import SceneWriter, default_workers, encode_png
    from fog_gym.encoding import encode_depth, semantic_to_carla_rgb
    from fog_gym.envs.fogdrive import FogDriveEnv
    from fog_gym.wrappers import FogWrapper

    env = FogWrapper(FogDriveEnv(town="highway"), ["light", "moderate", "dense"])
    obs, info = env.reset(seed=0)
    env.close()
    images = []
    for cam in ("CAM_FRONT", "CAM_BACK", "CAM_LEFT", "CAM_RIGHT"):
        images += [obs[cam]] + [obs[f"{cam}_FOG_{lv}"] for lv in ("LIGHT", "MODERATE", "DENSE")]
        images += [encode_depth(obs[f"{cam}_DEPTH"]), semantic_to_carla_rgb(obs[f"{cam}_SEM"])]
    cores = default_workers()
    configs = {"serial": 1, "2 threads": 2, f"{cores} threads (all cores)": cores}
    times: dict[str, list[float]] = {"PNG bound (serial)": [], **{k: [] for k in configs}}
    with tempfile.TemporaryDirectory() as tmp:
        writers = {k: SceneWriter(os.path.join(tmp, k.split()[0]), "data_collection_T1_day_run1_00000000", workers=w)
                   for k, w in configs.items()}  # fmt: skip
        for i in tqdm(range(repeats), desc="recorder", file=sys.stderr):
            times["PNG bound (serial)"].append(_ms(lambda: [encode_png(im) for im in images])[1])
            for k, w in writers.items():
                times[k].append(_ms(w.write_sample, i, obs, info)[1])
        for w in writers.values():
            w.close()
    med = {k: float(np.median(v)) for k, v in times.items()}
    return {"cores": cores, "ms": med, "speedup_vs_serial": {k: med["serial"] / med[k] for k in configs}}


def run_identity(steps: int) -> list[str]:
    from fog_gym.world.towns import TOWNS
    from tests.world.traffic_identity import PLAIN_SCENARIOS, compare_plain, compare_town

    done = []
    jobs = [("plain", e, c) for e, c in PLAIN_SCENARIOS] + [("town", t, None) for t in TOWNS]
    for kind, name, cfg in tqdm(jobs, desc="identity", file=sys.stderr):
        for seed in (0, 1, 2):
            ended = compare_plain(name, cfg, seed, steps) if kind == "plain" else compare_town(name, seed, steps)
            done.append(f"| {name} | {seed} | {steps} | {ended} | identical (≤ 1e-9) |")
    return done


def save_figure(scaling: dict[int, dict[str, float]], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = sorted(scaling)
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.loglog(n, [scaling[k]["reference_ms"] for k in n], "o-", label="highway-env (reference)")
    ax.loglog(n, [scaling[k]["fast_ms"] for k in n], "s-", label="fog-gym traffic core")
    ax.set_xlabel("vehicles_count")
    ax.set_ylabel("traffic step [ms] (2 × 20 Hz)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    fig.savefig(path, dpi=120)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=__doc__.split("\n\n", 1)[1])  # fmt: skip
    p.add_argument("--repeats", type=int, default=15, help="timed steps per configuration (default 15)")
    p.add_argument("--quick", action="store_true", help="smoke run: 3 repeats, 2 vehicle counts")
    p.add_argument("--vehicles", type=int, nargs="+", default=[10, 20, 40, 50, 100, 200], help="vehicle counts")
    p.add_argument("--identity", type=int, default=0, metavar="STEPS", help="also run the long identity check")
    p.add_argument("--skip-speed", action="store_true", help="only the identity check")
    p.add_argument("--skip-recorder", action="store_true", help="skip the recorder section (renders a full frame)")
    p.add_argument("--json", help="write the results as JSON here")
    p.add_argument("--figure", default="out/bench_traffic.png", help="traffic-scaling figure (PNG)")
    a = p.parse_args(argv)
    if a.repeats < 1:
        p.error(f"--repeats must be >= 1, got {a.repeats}")
    repeats = 3 if a.quick else a.repeats
    counts = [10, 50] if a.quick else a.vehicles
    res: dict[str, Any] = {"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"}
    lines = [f"# Traffic core benchmark ({res['machine']}, medians over {repeats} steps)", ""]
    if not a.skip_speed:
        res["scaling"] = bench_scaling(counts, repeats)
        lines += ["## Traffic step (highway town, 2 × 20 Hz sub-steps)", "",
                  "| vehicles_count | vehicles | highway-env [ms] | core [ms] | speed-up | speed-up (CPU time) |",
                  "|---|---|---|---|---|---|"]  # fmt: skip
        lines += [f"| {n} | {r['vehicles']} | {r['reference_ms']:.1f} | {r['fast_ms']:.1f} | {r['speedup']:.2f}× "
                  f"| {r['speedup_cpu']:.2f}× |" for n, r in res["scaling"].items()]  # fmt: skip
        save_figure(res["scaling"], a.figure)
        lines += ["", f"Figure: {a.figure}", ""]
        res["plain"] = bench_plain(repeats)
        res["rl"] = bench_rl(repeats)
        lines += ["## Steps per second", "", "| env | reference | core | speed-up | speed-up (CPU time) |",
                  "|---|---|---|---|---|",
                  f"| highway-v0 (observation included) | {res['plain']['reference_sps']:.1f} | {res['plain']['fast_sps']:.1f} | {res['plain']['speedup']:.2f}× | {res['plain']['speedup_cpu']:.2f}× |",
                  f"| FogDriveRL-v0 | {res['rl']['reference_sps']:.1f} | {res['rl']['fast_sps']:.1f} | {res['rl']['speedup']:.2f}× | {res['rl']['speedup_cpu']:.2f}× |", ""]  # fmt: skip
        res["profile"] = profile_fast(max(3, repeats // 2))
        lines += ["## cProfile of the core's traffic step (50 vehicles), own time", "", "| function | share |", "|---|---|"]
        lines += [f"| {f} | {s:.0%} |" for f, s in res["profile"]] + [""]
        if not a.skip_recorder:
            res["recorder"] = rec = bench_recorder(max(2, repeats // 3))
            lines += [f"## Recorder, ms per full-rig paired sample (35 files; {rec['cores']} cores)", "",
                      "| writer | ms | speed-up vs serial |", "|---|---|---|"]  # fmt: skip
            lines += [f"| {k} | {v:.0f} | {rec['speedup_vs_serial'].get(k, float('nan')):.2f}× |" for k, v in rec["ms"].items()]
            lines += [""]
    if a.identity:
        rows = run_identity(a.identity)
        res["identity"] = rows
        lines += ["## Identity (reference vs core)", "", "| env / town | seed | steps | episodes ended | result |",
                  "|---|---|---|---|---|", *rows, ""]  # fmt: skip
    print("\n".join(lines))
    if a.json:
        os.makedirs(os.path.dirname(os.path.abspath(a.json)), exist_ok=True)
        with open(a.json + ".tmp", "w") as f:
            json.dump(res, f, indent=1, default=str)
        os.replace(a.json + ".tmp", a.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
