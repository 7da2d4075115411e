"""Train one agent of the RL benchmark (or continue it from its checkpoint): a training condition's fog schedule on
the vector env, PPO or DQN, checkpoints of the model and the schedule's state every ``checkpoint`` steps."""

from __future__ import annotations

import os
import pickle
import time
from pathlib import Path
from typing import Any

from fog_gym.experiments.rl_bench.data import SENSOR_SETS, agent_name, policy_for, schedule_for, vec_env
from fog_gym.experiments.runner import write_atomic

ALGOS = ("PPO", "DQN")


def algo_class(name: str) -> Any:
    """The Stable-Baselines3 class of ``PPO`` or ``DQN``."""
    if name not in ALGOS:
        raise ValueError(f"algo must be one of {ALGOS}, got {name!r}")
    import stable_baselines3

    return getattr(stable_baselines3, name)


def new_model(algo: str, policy: str, env: Any, steps: int, n_envs: int, seed: int, device: str, tb: str,
              overrides: dict[str, Any] | None = None) -> Any:  # fmt: skip
    """A fresh agent. PPO: rollouts of ``min(512, steps / (2 n_envs))`` (≥ 64) steps per env, batches of 64, 4 epochs,
    learning rate 3·10⁻⁴, γ = 0.95. DQN: highway-env's DQN settings (replay of 15 000, learning from step 200 or a
    quarter of a short run, batches of 32, target update every 50 steps, learning rate 5·10⁻⁴) with γ = 0.95.
    ``overrides`` replace any of these (the study's ``--algo-kwarg``)."""
    cls = algo_class(algo)
    if algo == "PPO":
        kw = dict(n_steps=max(64, min(512, steps // (2 * n_envs))), batch_size=64, n_epochs=4, learning_rate=3e-4,
                  gamma=0.95)  # fmt: skip
    else:
        kw = dict(learning_rate=5e-4, buffer_size=15_000, learning_starts=min(200, steps // 4), batch_size=32, gamma=0.95,
                  train_freq=1, gradient_steps=1, target_update_interval=50)  # fmt: skip
    kw.update(overrides or {})
    return cls(policy, env, seed=seed, device=device, verbose=0, tensorboard_log=tb, **kw)


def _atomic_pickle(obj: Any, path: Path) -> None:
    write_atomic(path, pickle.dumps(obj))


def train_agent(config: Any, condition: str, seed: int, out: Path, progress: bool = True,
                sensors: str | None = None) -> dict[str, Any]:  # fmt: skip
    """Train (or resume) the agent ``<condition>_s<seed>`` of ``config`` (an :class:`~.study.RLConfig`; with a sensor
    set ``<sensors>_<condition>_s<seed>``, whose env observes that set) into ``out/models/<name>.zip``; returns its
    steps and training rate. A finished agent is not retrained."""
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor

    from fog_gym.rl.sb3 import VecFogCurriculum

    cls, steps, n_envs = algo_class(config.algo), config.steps, config.envs
    name = agent_name(condition, seed, sensors)
    kwargs = config.make_kwargs() if sensors is None else {**config.make_kwargs(), "sensors": SENSOR_SETS[sensors]}
    final = out / "models" / f"{name}.zip"
    if final.exists():
        return {"steps": steps, "trained": 0, "steps_per_s": None}
    ckpt_dir = out / "checkpoints" / name
    ckpt_dir.mkdir(parents=True, exist_ok=True)
    (out / "monitor").mkdir(parents=True, exist_ok=True)
    fog, schedule = schedule_for(condition, seed, steps, config.env_id, config.episode_seconds, config.episode_steps)
    venv = vec_env(config.vec_env, config.env_id, n_envs, fog, 1000 * seed, kwargs)
    state_path = ckpt_dir / "schedule.pkl"
    if schedule is not None:  # resumed: the curriculum (schedule, success history, counters) continues from the checkpoint
        state = pickle.loads(state_path.read_bytes()) if state_path.exists() else None
        venv = VecFogCurriculum(venv, state["curriculum"] if state else schedule)
    monitor_file = out / "monitor" / f"{name}_{len(list((out / 'monitor').glob(name + '_*')))}"
    env = VecMonitor(venv, filename=str(monitor_file))
    model_path, buffer_path = ckpt_dir / "model.zip", ckpt_dir / "replay.pkl"
    tb = str(out / "tb")
    if model_path.exists():
        model = cls.load(model_path, env=env, device=config.device, tensorboard_log=tb)
        if buffer_path.exists():
            model.load_replay_buffer(buffer_path)
    else:
        policy = policy_for(env.observation_space) if config.policy == "auto" else config.policy
        model = new_model(config.algo, policy, env, steps, n_envs, seed, config.device, tb, dict(config.algo_kwargs))
    checkpoint = config.checkpoint

    class Checkpoint(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % checkpoint < n_envs:
                self.model.save(ckpt_dir / ".model.tmp.zip")
                os.replace(ckpt_dir / ".model.tmp.zip", model_path)
                if hasattr(self.model, "replay_buffer"):  # off-policy (DQN): the buffer is not in the model file
                    self.model.save_replay_buffer(ckpt_dir / ".replay.tmp.pkl")
                    os.replace(ckpt_dir / ".replay.tmp.pkl", buffer_path)
                if schedule is not None:
                    _atomic_pickle({"curriculum": venv.curriculum}, state_path)
            return True

    remaining = steps - model.num_timesteps
    t0 = time.perf_counter()
    if remaining > 0:
        model.learn(remaining, callback=Checkpoint(), tb_log_name=name, reset_num_timesteps=False, progress_bar=progress)
    rate = max(remaining, 0) / max(time.perf_counter() - t0, 1e-9)
    final.parent.mkdir(parents=True, exist_ok=True)
    model.save(out / "models" / f".{name}.tmp.zip")
    os.replace(out / "models" / f".{name}.tmp.zip", final)
    env.close()
    return {"steps": steps, "trained": max(remaining, 0), "steps_per_s": rate}
