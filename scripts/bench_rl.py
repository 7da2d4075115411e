"""RL throughput of the native vector env against highway-env's highway-fast-v0, measured in one run.

Every rate is env steps per second of wall-clock time with uniformly random actions, resets included (an ended
episode restarts at once: ``NEXT_STEP`` autoreset in the vector envs, ``reset()`` in the single ones). Reported:

* highway-fast-v0 (plain highway-env: the pace this benchmark is a ratio of);
* the single envs and the native vector env (16 worlds) of ``FogDriveRL-v0`` and ``FogDriveRLHazard-v0``, pixels and
  perceived objects, each as a ratio of highway-fast-v0, in one process and sharded over 2 worker processes
  (``shards=2``);
* how the objects vector env scales from 1 to 32 worlds;
* a reset's cost in steps of the same env;
* where a vector step's time goes (traffic, perception or rendering, fog, the rest) from cProfile, in a run of its own
  (the rates are measured without the profiler, whose overhead falls on Python code);
* SB3 PPO end to end on the objects preset (16 worlds through ``fog_gym.rl.sb3.VectorEnvAdapter``, MLP policy,
  learner included) and the learner's share.

Targets (issue): objects ≥ 50× highway-fast-v0, pixels ≥ 10×, PPO ≥ 1000 steps/s, a reset ≤ ≈ 3 steps.

Run: python scripts/bench_rl.py [--seconds 10] [--quick] [--json out.json]
"""

from __future__ import annotations

import argparse
import cProfile
import json
import pstats
import time
from typing import Any

import numpy as np


def rate_single(make, seconds: float, seed: int = 0) -> float:
    env = make()
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    n = env.action_space.n
    for _ in range(10):  # warm-up (compiled kernels, caches)
        _, _, te, tr, _ = env.step(int(rng.integers(n)))
        if te or tr:
            env.reset()
    steps, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        _, _, te, tr, _ = env.step(int(rng.integers(n)))
        steps += 1
        if te or tr:
            env.reset()
    rate = steps / (time.perf_counter() - t0)
    env.close()
    return rate


def rate_vector(envs, seconds: float, seed: int = 0, profile: bool = False) -> tuple[float, Any]:
    envs.reset(seed=seed)
    rng = np.random.default_rng(seed)
    n = envs.num_envs
    for _ in range(5):
        envs.step(rng.integers(5, size=n))
    prof = cProfile.Profile() if profile else None
    steps, t0 = 0, time.perf_counter()
    if prof:
        prof.enable()
    while time.perf_counter() - t0 < seconds:
        envs.step(rng.integers(5, size=n))
        steps += n
    if prof:
        prof.disable()
    return steps / (time.perf_counter() - t0), prof


def reset_cost(make, repeats: int = 30) -> float:
    """A reset's wall time in steps of the same env (means over ``repeats`` each)."""
    env = make()
    env.reset(seed=0)
    for _ in range(3):
        env.step(1)
    t0 = time.perf_counter()
    for k in range(repeats):
        env.reset(seed=k)
    t_reset = (time.perf_counter() - t0) / repeats
    env.reset(seed=0)
    t0, steps = time.perf_counter(), 0
    while steps < repeats:
        _, _, te, tr, _ = env.step(1)
        steps += 1
        if te or tr:
            env.reset()
    t_step = (time.perf_counter() - t0) / steps
    return t_reset / t_step


#: cProfile functions (by name) → the stage they belong to.
STAGES = {
    "traffic": ("step_worlds",),
    "perception": ("perceive_worlds",),
    "camera rendering": ("render",),
    "LiDAR ray casting": ("simulate_lidar", "measure"),
    "fog": ("fog_images", "fog_lidar", "_fogged"),
    "bird's-eye image": ("observation",),
    "resets": ("reset_many", "reset"),
}


def breakdown(prof: cProfile.Profile) -> dict[str, float]:
    """Share of the profiled time per stage (cumulative time of the stage's outermost functions)."""
    stats = pstats.Stats(prof).stats
    total = max(sum(v[2] for v in stats.values()), 1e-9)  # total own time
    out: dict[str, float] = {}
    for stage, names in STAGES.items():
        t = max((v[3] for (f, line, fn), v in stats.items() if fn in names and "fog_gym" in f), default=0.0)
        out[stage] = t / total
    out["rest (Python, numpy, infos)"] = max(0.0, 1.0 - sum(out.values()))
    return out


def ppo_rate(steps: int, num_envs: int = 16) -> tuple[float, float]:
    """PPO end to end (rollouts + learner) on the objects hazard preset: steps/s and the learner's share."""
    import gymnasium as gym
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    import fog_gym  # noqa: F401
    from fog_gym.rl.sb3 import VectorEnvAdapter

    torch.set_num_threads(1)
    venv = VecMonitor(VectorEnvAdapter(gym.make_vec("FogDriveRLHazard-v0", num_envs=num_envs,
                                                    vectorization_mode="vector_entry_point", observation="objects",
                                                    info_detections=False)))  # fmt: skip
    model = PPO("MlpPolicy", venv, n_steps=128, batch_size=512, n_epochs=4, gamma=0.95, seed=0, device="cpu", verbose=0)
    train = model.train
    spent = [0.0]

    def timed_train() -> None:
        t = time.perf_counter()
        train()
        spent[0] += time.perf_counter() - t

    model.train = timed_train
    model.learn(2048)  # warm-up
    spent[0] = 0.0
    t0 = time.perf_counter()
    model.learn(steps, reset_num_timesteps=False)
    wall = time.perf_counter() - t0
    return steps / wall, spent[0] / wall


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seconds", type=float, default=10.0, help="measuring time per configuration (default 10)")
    p.add_argument("--quick", action="store_true", help="2 s per configuration, fewer scaling points, a short PPO run")
    p.add_argument("--ppo-steps", type=int, default=40960, help="PPO steps measured (default 40960)")
    p.add_argument("--json", help="also write the results to this JSON file")
    args = p.parse_args(argv)
    if args.seconds <= 0 or args.ppo_steps < 2048:
        p.error("--seconds must be > 0 and --ppo-steps >= 2048")
    sec = 2.0 if args.quick else args.seconds
    import gymnasium as gym
    import highway_env  # noqa: F401

    import fog_gym  # noqa: F401

    res: dict[str, Any] = {"seconds": sec}
    print("highway-fast-v0 …", flush=True)
    base = res["highway-fast-v0"] = rate_single(lambda: gym.make("highway-fast-v0"), sec)
    rows = []
    for env_id in ("FogDriveRL-v0", "FogDriveRLHazard-v0"):
        for obs in ("objects", "pixels"):
            print(f"{env_id} {obs} …", flush=True)
            single = rate_single(lambda: gym.make(env_id, observation=obs, fog="dense"), sec)
            venv = gym.make_vec(env_id, num_envs=16, vectorization_mode="vector_entry_point", observation=obs, fog="dense")
            vec = rate_vector(venv, sec)[0]
            prof = rate_vector(venv, min(sec, 3.0), seed=1, profile=True)[1]  # apart: cProfile slows Python down
            venv.close()
            cost = reset_cost(lambda: gym.make(env_id, observation=obs, fog="dense"))
            shards = 2
            venv = gym.make_vec(env_id, num_envs=16, vectorization_mode="vector_entry_point", observation=obs, fog="dense",
                                shards=shards)  # fmt: skip
            sharded = rate_vector(venv, sec)[0]
            venv.close()
            rows.append({"env": env_id, "observation": obs, "single": single, "vector16": vec, "reset_steps": cost,
                         "sharded16": sharded, "shards": shards, "breakdown": breakdown(prof)})  # fmt: skip
    res["presets"] = rows
    scaling = []
    for n in (1, 2, 4, 8, 16, 32) if not args.quick else (1, 4, 16):
        print(f"objects scaling {n} …", flush=True)
        venv = gym.make_vec("FogDriveRLHazard-v0", num_envs=n, vectorization_mode="vector_entry_point",
                            observation="objects", fog="dense")  # fmt: skip
        scaling.append((n, rate_vector(venv, sec)[0]))
        venv.close()
    res["scaling"] = scaling
    print("PPO …", flush=True)
    ppo, learner = ppo_rate(8192 if args.quick else args.ppo_steps)
    res["ppo"] = {"steps_per_s": ppo, "learner_share": learner}

    print(f"\nhighway-fast-v0: {base:.1f} steps/s (random actions, resets included)\n")
    print("| env | observation | single env [steps/s] | vector env, 16 worlds [steps/s] | × highway-fast-v0 | "
          "16 worlds in 2 processes (shards=2) [steps/s] | × highway-fast-v0 | reset [steps] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['env']} | {r['observation']} | {r['single']:.0f} | {r['vector16']:.0f} | "
              f"{r['vector16'] / base:.1f}× | {r['sharded16']:.0f} | {r['sharded16'] / base:.1f}× | "
              f"{r['reset_steps']:.1f} |")  # fmt: skip
    print("\nWhere a 16-world vector step goes (share of profiled time):\n")
    stages = list(rows[0]["breakdown"])
    print("| env | observation | " + " | ".join(stages) + " |")
    print("|---|---|" + "---|" * len(stages))
    for r in rows:
        print(f"| {r['env']} | {r['observation']} | " + " | ".join(f"{r['breakdown'][s]:.0%}" for s in stages) + " |")
    print("\nObjects vector env (FogDriveRLHazard-v0, dense fog) by number of worlds:\n")
    print("| worlds | steps/s | × highway-fast-v0 |\n|---|---|---|")
    for n, r in scaling:
        print(f"| {n} | {r:.0f} | {r / base:.1f}× |")
    print(f"\nSB3 PPO end to end (objects, 16 worlds, MLP): {ppo:.0f} steps/s, learner {learner:.0%} of the time")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
