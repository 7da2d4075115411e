"""Train one PPO agent per fog condition on FogDriveRL-v0: Clear, Light, Dense, Mixed, Curriculum.

Needs the ``rl`` extra (``pip install -e '.[rl]'``). TensorBoard logs go to ``<out>/tb``, models to
``<out>/models/<condition>.zip``. The default budget (``--steps 4000`` per condition, 2 subprocess envs) finishes
on a 2-core CPU in about 20 minutes together with ``examples/eval_matrix.py``'s default; use ``--steps`` for
real runs.

Run: python examples/train_curriculum.py --help
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

CONDITIONS = ("clear", "light", "dense", "mixed", "curriculum")


def make_vec_env(n_envs: int, fog, schedule=None, seed: int = 0):
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    import fog_gym  # noqa: F401
    from fog_gym.wrappers import FogCurriculum

    def factory(rank: int):
        def _make():
            env = gym.make("FogDriveRL-v0", fog=fog)
            if schedule is not None:
                env = FogCurriculum(env, schedule)
            env.reset(seed=seed + rank)
            return env

        return _make

    cls = SubprocVecEnv if n_envs > 1 else DummyVecEnv
    return VecMonitor(cls([factory(i) for i in range(n_envs)]))


def train(condition: str, steps: int, out: Path, n_envs: int = 2, seed: int = 0) -> Path:
    from stable_baselines3 import PPO

    from fog_gym.fog.schedules import MixedSampler, StepSchedule

    fog, schedule = {"clear": ("clear", None), "light": ("light", None), "dense": ("dense", None),
                     "mixed": ("clear", MixedSampler(seed=seed)),
                     "curriculum": ("clear", StepSchedule(episodes_per_level=max(1, steps // 400)))}[condition]  # fmt: skip
    env = make_vec_env(n_envs, fog, schedule, seed)
    model = PPO("MultiInputPolicy", env, n_steps=max(64, min(512, steps // (2 * n_envs))), batch_size=64, n_epochs=4,
                learning_rate=3e-4, gamma=0.95, seed=seed, verbose=0, tensorboard_log=str(out / "tb"))  # fmt: skip
    model.learn(total_timesteps=steps, tb_log_name=condition, progress_bar=True)
    path = out / "models" / f"{condition}.zip"
    path.parent.mkdir(parents=True, exist_ok=True)
    model.save(path)
    env.close()
    return path


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=4000, help="environment steps per condition (default 4000)")
    parser.add_argument("--conditions", nargs="+", choices=CONDITIONS, default=list(CONDITIONS))
    parser.add_argument("--envs", type=int, default=2, help="subprocess envs (default 2)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("out/rl"))
    args = parser.parse_args(argv)
    if args.steps < 64 or args.envs < 1:
        parser.error("--steps must be >= 64 and --envs >= 1")
    start = time.perf_counter()
    print(f"training {len(args.conditions)} condition(s) × {args.steps} steps; the default budget takes about "
          "13 minutes on a 2-core CPU (about 20 with examples/eval_matrix.py's default)")
    for k, condition in enumerate(args.conditions):
        t0 = time.perf_counter()
        path = train(condition, args.steps, args.out, args.envs, args.seed)
        took = time.perf_counter() - t0
        left = (time.perf_counter() - start) / (k + 1) * (len(args.conditions) - k - 1)
        print(f"{condition}: {args.steps} steps in {took:.0f} s ({args.steps / took:.1f} steps/s) -> {path}; "
              f"ETA {left / 60:.1f} min")


if __name__ == "__main__":
    main()
