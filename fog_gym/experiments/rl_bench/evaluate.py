"""Evaluate one trained agent of the RL benchmark at one test fog: deterministic episodes in a parallel vector env
on seeds 10⁶ + k (disjoint from training), per-episode return, collision, mean speed and distance driven."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.rl_bench.data import EVAL_SEED, POLICY_HZ, SENSOR_SETS, vec_env
from fog_gym.experiments.rl_bench.train import algo_class

#: (key, label, format) of every metric, in the report's order.
METRICS = (("collision", "collision rate", "{:.0%}"), ("return", "return", "{:.1f}"),
           ("speed", "mean speed [m/s]", "{:.1f}"), ("distance", "distance driven [m]", "{:.0f}"))  # fmt: skip


def evaluate(config: Any, model_path: Path, fog: str, episodes: int | None = None,
             sensors: str | None = None) -> dict[str, list[float]]:  # fmt: skip
    """``episodes`` (default ``config.episodes``) deterministic episodes of the agent at ``model_path`` in
    ``config.envs`` parallel envs (at most one per episode; observing sensor set ``sensors`` where given);
    per-episode metrics (:data:`METRICS`)."""
    episodes = config.episodes if episodes is None else episodes
    model = algo_class(config.algo).load(model_path, device=config.device)
    n = min(config.envs, episodes)
    kwargs = config.make_kwargs() if sensors is None else {**config.make_kwargs(), "sensors": SENSOR_SETS[sensors]}
    venv = vec_env(config.vec_env, config.env_id, n, fog, EVAL_SEED, kwargs)
    venv.seed(EVAL_SEED)
    obs = venv.reset()
    dt = 1.0 / POLICY_HZ
    started = n
    current = [{"return": 0.0, "speed": [], "crashed": False} for _ in range(n)]
    active = [True] * n
    results: dict[str, list[float]] = {"return": [], "collision": [], "speed": [], "distance": []}
    while any(active):
        action, _ = model.predict(obs, deterministic=True)
        obs, rewards, dones, infos = venv.step(action)
        for i in range(n):
            if not active[i]:
                continue
            current[i]["return"] += float(rewards[i])
            current[i]["speed"].append(float(infos[i].get("speed", 0.0)))
            current[i]["crashed"] |= bool(infos[i].get("crashed", False))
            if dones[i]:
                c = current[i]
                results["return"].append(c["return"])
                results["collision"].append(float(c["crashed"]))
                results["speed"].append(float(np.mean(c["speed"])))
                results["distance"].append(float(np.sum(c["speed"]) * dt))
                current[i] = {"return": 0.0, "speed": [], "crashed": False}
                if started < episodes:
                    started += 1
                else:
                    active[i] = False
    venv.close()
    return {k: v[:episodes] for k, v in results.items()}
