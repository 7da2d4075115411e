"""Behaviour cloning from a Minari dataset, evaluated in fog.

1. Record ``--episodes`` episodes of ``FogDriveRL-v0`` (``--fog``) driven by a privileged rule-based driver (it
   reads the true vehicle positions: keep right, overtake on the left when blocked, slow down when boxed in) into
   a Minari dataset with :func:`fog_gym.rl.minari.collect`.
2. Load it back with ``minari.load_dataset`` and train a small CNN on the observations (front camera + LiDAR
   bird's-eye view) to predict the driver's action (cross-entropy).
3. Evaluate the cloned policy, the driver and a random policy for ``--eval-episodes`` episodes at each of
   ``--eval-fog``; write ``bc.md`` (mean return ± std, crash rate) and ``bc.png``.

    python examples/bc_minari.py --episodes 20 --epochs 15 --eval-episodes 10 --out out/bc

Needs the ``minari`` and ``rl`` extras (torch) and matplotlib for the figure.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import fog_gym  # noqa: F401  (registers the envs)

LANE_LEFT, IDLE, LANE_RIGHT, FASTER, SLOWER = range(5)
LANE_WIDTH = 4.0  # highway-env's StraightLane.DEFAULT_WIDTH


class RuleDriver:
    """A privileged driver for the highway preset: reads the true scene, not the observation.

    With headway h = gap ahead in the ego lane / own speed: h < 2 s → change to a lane that is free from 10 m
    behind to 2.5 s ahead (left first) or slow down; else move right when that lane is free for 3 s; else speed up
    when h > 3 s and below 28 m/s, otherwise keep lane and speed.
    """

    def __init__(self, env: gym.Env) -> None:
        self.base = env.unwrapped
        self.lanes = int(self.base.config.highway_config.get("lanes_count", 4))

    def __call__(self, obs: Any) -> int:
        scene = self.base.scene
        x, y, yaw = scene.ego_pose
        v = scene.vehicles
        ego = v.ids == scene.ego_id
        speed = max(float(np.linalg.norm(v.velocities[ego][0, :2])) if ego.any() else 20.0, 5.0)
        others = ~ego
        d = v.centers[others, :2] - np.array([x, y])
        ahead = d @ np.array([math.cos(yaw), math.sin(yaw)])
        side = d @ np.array([-math.sin(yaw), math.cos(yaw)])  # + right (CARLA's y)
        lane = int(np.clip(round(y / LANE_WIDTH), 0, self.lanes - 1))

        def headway(offset: int) -> float:
            m = (np.abs(side - offset * LANE_WIDTH) < LANE_WIDTH / 2) & (ahead > 0)
            return float(ahead[m].min()) / speed if m.any() else math.inf

        def free(offset: int) -> bool:
            if not 0 <= lane + offset < self.lanes:
                return False
            m = np.abs(side - offset * LANE_WIDTH) < LANE_WIDTH / 2
            return not np.any(m & (ahead > -10.0) & (ahead < 2.5 * speed))

        h = headway(0)
        if h < 2.0:
            return LANE_LEFT if free(-1) else LANE_RIGHT if free(1) else SLOWER
        if free(1) and headway(1) > 3.0:
            return LANE_RIGHT
        return FASTER if h > 3.0 and speed < 28.0 else IDLE


def to_tensor(observations: dict[str, np.ndarray]):
    """Stack CAM_FRONT (3, H, W) and LIDAR_BEV (2, H, W) into float channels in [0, 1]."""
    import torch

    return torch.from_numpy(np.concatenate([observations["CAM_FRONT"], observations["LIDAR_BEV"]], axis=-3)).float() / 255.0


def make_model(channels: int = 5, actions: int = 5):
    import torch.nn as nn

    return nn.Sequential(
        nn.Conv2d(channels, 16, 5, stride=2, padding=2), nn.ReLU(),
        nn.Conv2d(16, 32, 3, stride=2, padding=1), nn.ReLU(),
        nn.Conv2d(32, 32, 3, stride=2, padding=1), nn.ReLU(),
        nn.AdaptiveAvgPool2d(4), nn.Flatten(), nn.Linear(512, 64), nn.ReLU(), nn.Linear(64, actions),
    )  # fmt: skip


def load_pairs(dataset) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """(observations, actions) of every step of a Minari dataset (the last observation of an episode dropped)."""
    obs: dict[str, list] = {"CAM_FRONT": [], "LIDAR_BEV": []}
    acts = []
    for ep in dataset.iterate_episodes():
        for k in obs:
            obs[k].append(np.asarray(ep.observations[k])[:-1])
        acts.append(np.asarray(ep.actions))
    return {k: np.concatenate(v) for k, v in obs.items()}, np.concatenate(acts).astype(np.int64)


def train_bc(dataset, epochs: int = 15, seed: int = 0, progress: bool = True):
    """Fit the CNN to the dataset's (observation, action) pairs; returns (model, training accuracy per epoch)."""
    import torch
    from tqdm import tqdm

    torch.manual_seed(seed)
    obs, acts = load_pairs(dataset)
    x, y = to_tensor(obs), torch.from_numpy(acts)
    model = make_model()
    opt = torch.optim.Adam(model.parameters(), lr=2e-3)
    gen = torch.Generator().manual_seed(seed)
    accuracy = []
    for _ in tqdm(range(epochs), desc="behaviour cloning", unit="epoch", disable=not progress):
        model.train()
        for idx in torch.randperm(len(y), generator=gen).split(64):
            loss = torch.nn.functional.cross_entropy(model(x[idx]), y[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
        model.eval()
        with torch.no_grad():
            accuracy.append(float((model(x).argmax(1) == y).float().mean()))
    return model, accuracy


def bc_policy(model):
    import torch

    def act(obs: dict[str, np.ndarray]) -> int:
        with torch.no_grad():
            return int(model(to_tensor({k: obs[k][None] for k in ("CAM_FRONT", "LIDAR_BEV")})).argmax(1)[0])

    return act


def evaluate(make_policy, fog: Any, episodes: int, seconds: float, seed: int = 10_000, label: str = "",
             progress: bool = True) -> dict[str, float]:  # fmt: skip
    """Mean/std return and crash rate over ``episodes`` episodes (seeds ``seed + k``) at ``fog``."""
    from tqdm import tqdm

    env = gym.make("FogDriveRL-v0", fog=fog, episode_seconds=seconds)
    env.action_space.seed(seed)
    policy = make_policy(env)
    returns, crashes = [], 0
    for k in tqdm(range(episodes), desc=f"evaluating {label} @ {fog}", unit="episode", disable=not progress):
        obs, info = env.reset(seed=seed + k)
        total, done = 0.0, False
        while not done:
            obs, r, terminated, truncated, info = env.step(policy(obs))
            total += float(r)
            done = terminated or truncated
        returns.append(total)
        crashes += bool(info.get("crashed", False))
    env.close()
    return {"mean": float(np.mean(returns)), "std": float(np.std(returns)), "crash_rate": crashes / episodes}


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="bc_minari.py", description=__doc__.split("\n\n")[0])
    p.add_argument("--fog", default="dense", help="fog level of the recorded episodes (default dense)")
    p.add_argument("--episodes", type=int, default=20, help="episodes recorded by the rule driver (default 20)")
    p.add_argument("--episode-seconds", type=float, default=20.0, help="episode length (default 20 s = 100 steps)")
    p.add_argument("--epochs", type=int, default=15, help="training epochs (default 15)")
    p.add_argument("--eval-episodes", type=int, default=10, help="evaluation episodes per policy and fog (default 10)")
    p.add_argument("--eval-fog", nargs="+", default=["clear", "dense"], help="fog levels to evaluate at")
    p.add_argument("--dataset-id", default=None, help="Minari id (default fog-gym/highway-<fog>-rule-v0)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first recorded episode (default 0)")
    p.add_argument("--out", type=Path, default=Path("out/bc"), help="output folder (default out/bc)")
    args = p.parse_args(argv)
    for name in ("episodes", "epochs", "eval_episodes"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1")
    import minari

    from fog_gym.rl.minari import collect

    dataset_id = args.dataset_id or f"fog-gym/highway-{args.fog}-rule-v0"
    env = gym.make("FogDriveRL-v0", fog=args.fog, episode_seconds=args.episode_seconds)
    collect(env, RuleDriver(env), episodes=args.episodes, dataset_id=dataset_id, seed=args.seed,
            algorithm_name="rule-driver", overwrite=True)  # fmt: skip
    env.close()
    dataset = minari.load_dataset(dataset_id)
    model, accuracy = train_bc(dataset, args.epochs, args.seed)
    policies = {"behaviour cloning": lambda e: bc_policy(model), "rule driver": RuleDriver,
                "random": lambda e: (lambda obs: e.action_space.sample())}  # fmt: skip
    results = {name: {str(f): evaluate(make, f, args.eval_episodes, args.episode_seconds, label=name)
                      for f in args.eval_fog}
               for name, make in policies.items()}  # fmt: skip
    args.out.mkdir(parents=True, exist_ok=True)
    lines = [f"Dataset `{dataset_id}`: {dataset.total_episodes} episodes, {dataset.total_steps} steps at fog "
             f"{args.fog}; training accuracy {accuracy[-1]:.3f} after {args.epochs} epochs.", "",
             "| policy | " + " | ".join(f"return @ {f} | crashes @ {f}" for f in args.eval_fog) + " |",
             "|---|" + "---|---|" * len(args.eval_fog)]  # fmt: skip
    for name, per_fog in results.items():
        cells = [f"{r['mean']:.2f} ± {r['std']:.2f} | {r['crash_rate']:.0%}" for r in per_fog.values()]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    (args.out / "bc.md").write_text("\n".join(lines) + "\n")
    (args.out / "bc.json").write_text(json.dumps({"accuracy": accuracy, "results": results}, indent=1))
    _figure(results, args.out / "bc.png", f"{args.eval_episodes} episodes per bar; trained on fog {args.fog}")
    print("\n".join(lines))
    return {"accuracy": accuracy, "results": results}


def _figure(results: dict, path: Path, note: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fogs = list(next(iter(results.values())))
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    width = 0.8 / len(results)
    for i, (name, per_fog) in enumerate(results.items()):
        xs = np.arange(len(fogs)) + i * width
        ax.bar(xs, [per_fog[f]["mean"] for f in fogs], width, yerr=[per_fog[f]["std"] for f in fogs], label=name,
               capsize=3)  # fmt: skip
    ax.set_xticks(np.arange(len(fogs)) + width * (len(results) - 1) / 2, [f"fog: {f}" for f in fogs])
    ax.set_ylabel("episode return")
    ax.set_title(f"Behaviour cloning from a Minari dataset ({note})", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
