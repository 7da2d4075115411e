"""PPO in one file, CleanRL-style (CleanRL's ppo.py defaults: 4 × 128-step rollouts, 4 epochs of 4 minibatches,
Adam 2.5e-4 annealed, GAE 0.95, clip 0.2, entropy 0.01, a 64-64 tanh MLP, no reward normalisation), on
FogDriveRLObjects-v0 through the Gymnasium API only: ``gym.make_vec`` and Gymnasium's own
``RecordEpisodeStatistics``. Writes the learning curve (CSV and PNG) to --out.

    python examples/cleanrl_ppo.py --total-timesteps 100000 --fog dense --out out/cleanrl_ppo

Needs torch (the ``rl`` extra) and matplotlib.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env-id", default="FogDriveRLObjects-v0", help="env id (default FogDriveRLObjects-v0)")
    p.add_argument("--fog", default="clear", help="fog level: clear, light, moderate, dense or metres (default clear)")
    p.add_argument("--total-timesteps", type=int, default=100_000, help="env steps in all (default 100000)")
    p.add_argument("--num-envs", type=int, default=4, help="parallel sub-envs (default 4)")
    p.add_argument("--num-steps", type=int, default=128, help="steps per sub-env per rollout (default 128)")
    p.add_argument("--learning-rate", type=float, default=2.5e-4, help="Adam's step size, annealed to 0 (default 2.5e-4)")
    p.add_argument("--seed", type=int, default=1, help="seed of torch, numpy and the envs (default 1)")
    p.add_argument("--out", type=Path, default=Path("out/cleanrl_ppo"), help="output folder (default out/cleanrl_ppo)")
    a = p.parse_args(argv)
    if a.total_timesteps < a.num_envs * a.num_steps:
        p.error("--total-timesteps must cover at least one rollout (--num-envs × --num-steps)")
    return a


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    import gymnasium as gym
    import numpy as np
    import torch
    import torch.nn as nn
    from torch.distributions.categorical import Categorical

    import fog_gym  # noqa: F401  (registers the envs)

    gamma, gae_lambda, clip, ent_coef, vf_coef, max_grad_norm, epochs, minibatches = 0.99, 0.95, 0.2, 0.01, 0.5, 0.5, 4, 4
    torch.manual_seed(args.seed)
    np.random.seed(args.seed)
    torch.set_num_threads(1)
    envs = gym.make_vec(args.env_id, num_envs=args.num_envs, vectorization_mode="vector_entry_point", fog=args.fog)
    envs = gym.wrappers.vector.RecordEpisodeStatistics(envs)
    obs_dim = int(np.prod(envs.single_observation_space.shape))
    n_actions = int(envs.single_action_space.n)

    def layer(i: int, o: int, std: float = np.sqrt(2)) -> nn.Linear:
        lin = nn.Linear(i, o)
        nn.init.orthogonal_(lin.weight, std)
        nn.init.constant_(lin.bias, 0.0)
        return lin

    critic = nn.Sequential(layer(obs_dim, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, 1, 1.0))
    actor = nn.Sequential(layer(obs_dim, 64), nn.Tanh(), layer(64, 64), nn.Tanh(), layer(64, n_actions, 0.01))
    params = [*critic.parameters(), *actor.parameters()]
    optimizer = torch.optim.Adam(params, lr=args.learning_rate, eps=1e-5)

    n, t = args.num_envs, args.num_steps
    batch = n * t
    obs_buf = torch.zeros((t, n, obs_dim))
    act_buf, logp_buf, rew_buf, done_buf, val_buf = (torch.zeros((t, n)) for _ in range(5))
    obs, _ = envs.reset(seed=args.seed)
    next_obs = torch.as_tensor(obs, dtype=torch.float32).reshape(n, -1)
    next_done = torch.zeros(n)
    rows, step, t0 = [], 0, time.time()
    iterations = args.total_timesteps // batch
    args.out.mkdir(parents=True, exist_ok=True)
    for it in range(1, iterations + 1):
        for g in optimizer.param_groups:
            g["lr"] = (1.0 - (it - 1.0) / iterations) * args.learning_rate
        for k in range(t):
            step += n
            obs_buf[k], done_buf[k] = next_obs, next_done
            with torch.no_grad():
                dist = Categorical(logits=actor(next_obs))
                action = dist.sample()
                logp_buf[k], val_buf[k] = dist.log_prob(action), critic(next_obs).flatten()
            act_buf[k] = action
            obs, reward, term, trunc, infos = envs.step(action.numpy())
            rew_buf[k] = torch.as_tensor(reward, dtype=torch.float32)
            next_obs = torch.as_tensor(obs, dtype=torch.float32).reshape(n, -1)
            next_done = torch.as_tensor(np.logical_or(term, trunc), dtype=torch.float32)
            if "episode" in infos:  # Gymnasium's RecordEpisodeStatistics: the episodes that ended in this step
                for i in np.flatnonzero(infos["_episode"]):
                    rows.append({"step": step, "return": float(infos["episode"]["r"][i]),
                                 "length": int(infos["episode"]["l"][i]), "crashed": bool(infos["crashed"][i])})  # fmt: skip
        with torch.no_grad():  # generalised advantage estimates (NEXT_STEP autoreset: a done cuts the bootstrap)
            next_value = critic(next_obs).flatten()
            adv = torch.zeros_like(rew_buf)
            last = torch.zeros(n)
            for k in reversed(range(t)):
                nonterminal = 1.0 - (next_done if k == t - 1 else done_buf[k + 1])
                value_next = next_value if k == t - 1 else val_buf[k + 1]
                delta = rew_buf[k] + gamma * value_next * nonterminal - val_buf[k]
                last = delta + gamma * gae_lambda * nonterminal * last
                adv[k] = last
            returns = adv + val_buf
        b_obs, b_act, b_logp = obs_buf.reshape(batch, -1), act_buf.reshape(-1), logp_buf.reshape(-1)
        b_adv, b_ret, b_val = adv.reshape(-1), returns.reshape(-1), val_buf.reshape(-1)
        for _ in range(epochs):
            order = torch.randperm(batch)
            for mb in order.split(batch // minibatches):
                dist = Categorical(logits=actor(b_obs[mb]))
                logp = dist.log_prob(b_act[mb])
                ratio = (logp - b_logp[mb]).exp()
                a = b_adv[mb]
                a = (a - a.mean()) / (a.std() + 1e-8)
                pg = torch.max(-a * ratio, -a * ratio.clamp(1 - clip, 1 + clip)).mean()
                v = critic(b_obs[mb]).flatten()
                v_clipped = b_val[mb] + (v - b_val[mb]).clamp(-clip, clip)
                v_loss = 0.5 * torch.max((v - b_ret[mb]) ** 2, (v_clipped - b_ret[mb]) ** 2).mean()
                loss = pg - ent_coef * dist.entropy().mean() + vf_coef * v_loss
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(params, max_grad_norm)
                optimizer.step()
        recent = [r["return"] for r in rows[-20:]]
        print(f"iteration {it}/{iterations}  step {step}  mean return (last 20 episodes) "
              f"{np.mean(recent) if recent else float('nan'):.2f}  {step / (time.time() - t0):.0f} steps/s", flush=True)  # fmt: skip
    envs.close()
    with open(args.out / "curve.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["step", "return", "length", "crashed"])
        w.writeheader()
        w.writerows(rows)
    _figure(rows, args, time.time() - t0)


def _figure(rows: list[dict], args: argparse.Namespace, seconds: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    steps = np.array([r["step"] for r in rows])
    ret = np.array([r["return"] for r in rows])
    crashed = np.array([r["crashed"] for r in rows], float)
    k = max(1, len(rows) // 25)
    smooth = np.convolve(ret, np.ones(k) / k, mode="valid")
    crash_rate = np.convolve(crashed, np.ones(k) / k, mode="valid")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8), layout="constrained")
    a1.plot(steps, ret, ".", alpha=0.25, ms=3, label="episode")
    a1.plot(steps[k - 1 :], smooth, lw=2, label=f"mean of {k}")
    a1.set_xlabel("env steps")
    a1.set_ylabel("episode return")
    a1.legend(fontsize=8)
    a2.plot(steps[k - 1 :], crash_rate, lw=2, color="C3")
    a2.set_xlabel("env steps")
    a2.set_ylabel(f"collision rate (mean of {k} episodes)")
    a2.set_ylim(0, 1)
    for ax in (a1, a2):
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
    fig.suptitle(f"CleanRL-style PPO on {args.env_id}, fog {args.fog}, seed {args.seed} ({seconds / 60:.1f} min)")
    fig.savefig(args.out / "curve.png", dpi=100)
    print(f"wrote {args.out / 'curve.csv'} and {args.out / 'curve.png'}")


if __name__ == "__main__":
    main()
