"""The fog RL benchmark: train PPO per fog condition and training seed, evaluate every agent on every test fog in
parallel vector envs, and report a train × test matrix with confidence intervals across training seeds.

Conditions: clear, light, dense (fixed fog), mixed (a seeded level per episode), curriculum (clear → 160 → 100 →
50 m in steps), success (advance when 80 % of the last 10 episodes were crash-free) and continuous (visibility
sliding from clear to 50 m linearly in α). Schedules are applied by ``fog_gym.rl.sb3.VecFogCurriculum`` at the very
next episode of each sub-env. PPO runs on the GPU when one is present (``--device auto``).

Per cell the matrix gives the mean over training seeds of each agent's mean over ``--episodes`` evaluation
episodes, with a 95 % Student-t interval across training seeds (``n/a`` for one seed) and, in brackets, the
episode-level standard deviation; metrics: collision rate, return, mean speed [m/s], distance driven [m].
Evaluation seeds (10⁶ + k) are disjoint from training seeds. Outputs under ``--out``: ``matrix.md``,
``matrix.json``, ``heatmap.png`` (collision rate and return), ``fog_effect.png`` (both against the test fog,
with the CIs as error bars), ``curves.png`` (every condition's learning curve)
and ``curves/<condition>.png`` (each training seed's),
TensorBoard logs in ``tb/``, models in ``models/``.

Resumable: training checkpoints (model + schedule state) every ``--checkpoint`` steps and evaluation results per
(agent, test fog) are kept; run the same command again and it continues where it stopped.

The default budget (7 conditions × 1 seed × 2 048 steps, 8 episodes per cell, 2 envs) finishes in about 20
minutes on a 2-core CPU — a smoke run, far too small for a finding. A study: ``--seeds 3 --steps 50000
--episodes 32 --envs 16`` (about an hour on a 16-core machine with a GPU).

Run: python scripts/rl_benchmark.py --help
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pickle
import time
from pathlib import Path
from typing import Any

import numpy as np

CONDITIONS = ("clear", "light", "dense", "mixed", "curriculum", "success", "continuous")
TEST_LEVELS = ("clear", "light", "moderate", "dense")
METRICS = (("collision", "collision rate", "{:.0%}"), ("return", "return", "{:.1f}"),
           ("speed", "mean speed [m/s]", "{:.1f}"), ("distance", "distance driven [m]", "{:.0f}"))  # fmt: skip
EVAL_SEED = 1_000_000


#: Mean training-episode length [policy steps] of each task, to spread the schedules over a run: FogDriveRL-v0's
#: agents rarely crash (100 steps per 20 s); FogDriveRLHazard-v0's crash often (25–37 steps measured over the first
#: seed's 5×10⁴-step runs of every fixed condition).
EPISODE_STEPS = {"FogDriveRL-v0": 100, "FogDriveRLHazard-v0": 30}


def schedule_for(condition: str, seed: int, steps: int):
    """``(initial fog, schedule or None)`` of a training condition. The step curriculum reaches dense fog after
    60 % of the run's expected episodes, the continuous one after 80 % (see :data:`EPISODE_STEPS`)."""
    from fog_gym.fog.schedules import ContinuousSchedule, MixedSampler, StepSchedule, SuccessSchedule

    length = min(EPISODE_STEPS[ENV_ID["value"]], max(1, round(EPISODE_SECONDS["value"] * 5)))  # 5 Hz policy
    episodes = max(4, steps // length)
    return {
        "clear": ("clear", None), "light": ("light", None), "dense": ("dense", None),
        "mixed": ("clear", MixedSampler(seed=seed)),
        "curriculum": ("clear", StepSchedule(episodes_per_level=max(1, episodes // 5))),
        "success": ("clear", SuccessSchedule()),
        "continuous": ("clear", ContinuousSchedule(episodes=max(1, episodes * 4 // 5))),
    }[condition]  # fmt: skip


EPISODE_SECONDS = {"value": 20.0}  # FogDriveRL-v0's default; --episode-seconds shortens episodes for smoke runs
ENVS = ("FogDriveRL-v0", "FogDriveRLHazard-v0")
ENV_ID = {"value": ENVS[0]}  # --env


def _make_env(fog: Any, seed: int):
    seconds, env_id = EPISODE_SECONDS["value"], ENV_ID["value"]

    def make():
        import gymnasium as gym

        import fog_gym  # noqa: F401  (registers the env in the worker)

        env = gym.make(env_id, fog=fog, episode_seconds=seconds)
        env.reset(seed=seed)
        return env

    return make


def vec_env(n: int, fog: Any, seed: int):
    """``n`` FogDriveRL-v0 envs in subprocesses (one in-process env for ``n = 1``), seeded ``seed + rank``."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    cls = SubprocVecEnv if n > 1 else DummyVecEnv
    return cls([_make_env(fog, seed + r) for r in range(n)])


def _atomic_save(obj: Any, path: Path) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "wb") as f:
        pickle.dump(obj, f)
    os.replace(tmp, path)


def train(condition: str, seed: int, steps: int, out: Path, n_envs: int, device: str, checkpoint: int) -> Path:
    """Train (or resume) one agent; returns its model path. Skips a finished one."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecMonitor

    from fog_gym.rl.sb3 import VecFogCurriculum

    name = f"{condition}_s{seed}"
    final = out / "models" / f"{name}.zip"
    if final.exists():
        return final
    ckpt_dir = out / "checkpoints" / name
    ckpt_dir.mkdir(parents=True, exist_ok=True)
    (out / "monitor").mkdir(parents=True, exist_ok=True)
    fog, schedule = schedule_for(condition, seed, steps)
    venv = vec_env(n_envs, fog, 1000 * seed)
    state_path = ckpt_dir / "schedule.pkl"
    if schedule is not None:  # resumed: the curriculum (schedule, success history, counters) continues from the checkpoint
        state = pickle.loads(state_path.read_bytes()) if state_path.exists() else None
        venv = VecFogCurriculum(venv, state["curriculum"] if state else schedule)
    monitor_file = out / "monitor" / f"{name}_{len(list((out / 'monitor').glob(name + '_*')))}"
    env = VecMonitor(venv, filename=str(monitor_file))
    model_path = ckpt_dir / "model.zip"
    if model_path.exists():
        model = PPO.load(model_path, env=env, device=device, tensorboard_log=str(out / "tb"))
    else:
        model = PPO("MultiInputPolicy", env, n_steps=max(64, min(512, steps // (2 * n_envs))), batch_size=64,
                    n_epochs=4, learning_rate=3e-4, gamma=0.95, seed=seed, device=device, verbose=0,
                    tensorboard_log=str(out / "tb"))  # fmt: skip

    class Checkpoint(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps % checkpoint < n_envs:
                self.model.save(ckpt_dir / ".model.tmp.zip")
                os.replace(ckpt_dir / ".model.tmp.zip", model_path)
                if schedule is not None:
                    _atomic_save({"curriculum": venv.curriculum}, state_path)
            return True

    remaining = steps - model.num_timesteps
    t0 = time.perf_counter()
    if remaining > 0:
        model.learn(remaining, callback=Checkpoint(), tb_log_name=name, reset_num_timesteps=False, progress_bar=True)
    rate = max(remaining, 0) / max(time.perf_counter() - t0, 1e-9)
    final.parent.mkdir(parents=True, exist_ok=True)
    model.save(out / "models" / f".{name}.tmp.zip")
    os.replace(out / "models" / f".{name}.tmp.zip", final)
    env.close()
    print(f"{name}: {steps} steps ({rate:.0f} steps/s) -> {final}")
    return final


def evaluate(model_path: Path, fog: str, episodes: int, n_envs: int, device: str) -> dict[str, list[float]]:
    """``episodes`` deterministic episodes in a parallel vector env on seeds 10⁶ + k; per-episode metrics."""
    from stable_baselines3 import PPO

    model = PPO.load(model_path, device=device)
    n = min(n_envs, episodes)
    venv = vec_env(n, fog, EVAL_SEED)
    venv.seed(EVAL_SEED)
    obs = venv.reset()
    dt = 1.0 / 5.0  # FogDriveRL-v0's policy period [s]
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


def ci95_across(values: list[float]) -> float | None:
    """Half-width of the 95 % Student-t interval of the mean of ``values``; None for fewer than two.

    >>> round(ci95_across([1.0, 2.0, 3.0]), 3)
    2.484
    >>> ci95_across([1.0]) is None
    True
    """
    if len(values) < 2:
        return None
    from scipy import stats

    return float(stats.t.ppf(0.975, len(values) - 1) * np.std(values, ddof=1) / math.sqrt(len(values)))


def aggregate(results: dict[str, dict[str, dict[int, dict[str, list[float]]]]]) -> dict[str, Any]:
    """``results[condition][test][seed][metric]`` → per cell mean over seeds, CI across seeds, episode spread."""
    table: dict[str, Any] = {}
    for cond, tests in results.items():
        for test, seeds in tests.items():
            for metric, *_ in METRICS:
                per_seed = [float(np.mean(seeds[s][metric])) for s in sorted(seeds)]
                episodes = [v for s in sorted(seeds) for v in seeds[s][metric]]
                table.setdefault(cond, {}).setdefault(test, {})[metric] = {
                    "mean": float(np.mean(per_seed)), "ci95": ci95_across(per_seed), "seeds": len(per_seed),
                    "episode_std": float(np.std(episodes, ddof=1)) if len(episodes) > 1 else 0.0,
                    "episodes": len(episodes),
                }  # fmt: skip
    return table


def render_matrix(table: dict[str, Any], meta: dict[str, Any]) -> str:
    lines = [f"# {meta.get('env', ENVS[0])} fog benchmark: train × test matrix", "",
             f"{meta['seeds']} training seed(s) × {meta['steps']} steps per condition, {meta['episodes']} evaluation "
             f"episodes per agent and test fog (seeds {EVAL_SEED}+). Cells: mean over training seeds ± 95 % CI across "
             "seeds (n/a for one seed) [episode-level SD].", ""]  # fmt: skip
    for metric, label, fmt in METRICS:
        lines += [f"## {label}", "", "| trained on \\ tested on | " + " | ".join(TEST_LEVELS) + " |",
                  "|---|" + "---|" * len(TEST_LEVELS)]  # fmt: skip
        for cond in [c for c in CONDITIONS if c in table]:
            cells = []
            for test in TEST_LEVELS:
                c = table[cond][test][metric]
                ci = "n/a" if c["ci95"] is None else fmt.format(c["ci95"])
                cells.append(f"{fmt.format(c['mean'])} ± {ci} [{fmt.format(c['episode_std'])}]")
            lines.append(f"| {cond} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += significance(table)
    return "\n".join(lines)


def _verdict(a: dict[str, Any], b: dict[str, Any]) -> str:
    if a["ci95"] is None or b["ci95"] is None:
        return "not testable (one seed)"
    separated = a["mean"] + a["ci95"] < b["mean"] - b["ci95"] or b["mean"] + b["ci95"] < a["mean"] - a["ci95"]
    return "separated" if separated else "CIs overlap"


def significance(table: dict[str, Any]) -> list[str]:
    """Plain statements from the 95 % CIs across training seeds (separated = the intervals do not overlap):
    the fog effect (each condition's agents tested clear against tested dense) and each condition against the
    clear-trained agents, tested clear and tested dense, on collision rate and return.

    >>> cell = lambda m, ci: {"collision": {"mean": m, "ci95": ci}, "return": {"mean": 10 * m, "ci95": 10 * ci}}
    >>> t = {"clear": {"clear": cell(0.2, 0.05), "dense": cell(0.8, 0.1)}}
    >>> significance(t)[4]
    '- clear: collision rate 20% clear vs 80% dense — separated; return 2.0 vs 8.0 — separated'
    """
    out = ["## Separated? (95 % CIs across training seeds that do not overlap)", "",
           "Fog effect (the same agents tested in clear air and in dense fog):", ""]  # fmt: skip
    conds = [c for c in CONDITIONS if c in table]
    for cond in conds:
        a, b = table[cond]["clear"], table[cond]["dense"]
        out.append(f"- {cond}: collision rate {a['collision']['mean']:.0%} clear vs {b['collision']['mean']:.0%} dense "
                   f"— {_verdict(a['collision'], b['collision'])}; return {a['return']['mean']:.1f} vs "
                   f"{b['return']['mean']:.1f} — {_verdict(a['return'], b['return'])}")  # fmt: skip
    if "clear" not in table:
        return out + ["", "(no clear-trained agent)"]
    out += ["", "Against the clear-trained agents:", ""]
    for test in ("clear", "dense"):
        ref = table["clear"][test]
        for cond in [c for c in conds if c != "clear"]:
            c = table[cond][test]
            out.append(f"- tested {test}: {cond} collision rate {c['collision']['mean']:.0%} vs clear "
                       f"{ref['collision']['mean']:.0%} — {_verdict(c['collision'], ref['collision'])}; return "
                       f"{c['return']['mean']:.1f} vs {ref['return']['mean']:.1f} — {_verdict(c['return'], ref['return'])}")  # fmt: skip
    return out


def wall_times(out: Path, conditions: list[str], seeds: list[int], episodes: int) -> dict[str, dict[str, float | None]]:
    """Training wall time and steps of each agent from its VecMonitor logs (summed over resumed parts; each part's
    time runs from its start to its last finished episode), and its evaluation wall time when every one of its
    cells of ``episodes`` episodes recorded it (None otherwise)."""
    times: dict[str, dict[str, float]] = {}
    for cond in conditions:
        for seed in seeds:
            name, wall, steps = f"{cond}_s{seed}", 0.0, 0.0
            for f in sorted((out / "monitor").glob(f"{name}_*.monitor.csv")):
                rows = _monitor_rows(f)
                if rows.size:
                    wall += float(rows[-1, 2])
                    steps += float(rows[:, 1].sum())
            evals = [json.loads(p.read_text()).get("wall_s") for p in (out / "eval").glob(f"{name}_*_{episodes}.json")]
            # cells evaluated before timing was recorded have none: then the agent's evaluation time is unknown
            timed = bool(evals) and all(e is not None for e in evals)
            times[name] = {"train_s": wall, "steps": steps, "eval_s": float(sum(evals)) if timed else None}
    return times


def render_wall_times(times: dict[str, dict[str, float | None]]) -> list[str]:
    lines = ["## Wall time", "", "| agent | training [min] | steps/s | evaluation [min] |", "|---|---|---|---|"]
    for name, t in times.items():
        rate = t["steps"] / t["train_s"] if t["train_s"] > 0 else float("nan")
        ev = "—" if t["eval_s"] is None else f"{t['eval_s'] / 60:.1f}"
        lines.append(f"| {name} | {t['train_s'] / 60:.1f} | {rate:.0f} | {ev} |")
    total = sum(t["train_s"] for t in times.values())
    return lines + ["", f"Training in all: {total / 3600:.2f} h of wall time (from the monitor logs)."]


def figures(table: dict[str, Any], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    conds = [c for c in CONDITIONS if c in table]
    fig, axes = plt.subplots(1, 2, figsize=(11, 0.55 * len(conds) + 2), dpi=120)
    for ax, (metric, label, fmt) in zip(axes, METRICS[:2]):
        grid = np.array([[table[c][t][metric]["mean"] for t in TEST_LEVELS] for c in conds])
        im = ax.imshow(grid, cmap="magma_r" if metric == "collision" else "viridis")
        ax.set_xticks(range(len(TEST_LEVELS)), TEST_LEVELS)
        ax.set_yticks(range(len(conds)), conds)
        ax.set_xlabel("tested on")
        ax.set_ylabel("trained on")
        for i in range(len(conds)):
            for j in range(len(TEST_LEVELS)):
                ax.text(j, i, fmt.format(grid[i, j]), ha="center", va="center", color="w", fontsize=8)
        fig.colorbar(im, ax=ax, label=label)
        ax.set_title(label)
    fig.tight_layout()
    fig.savefig(out / "heatmap.png")
    plt.close(fig)
    # the same means against the test fog, with the 95 % CIs across training seeds as error bars
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), dpi=120)
    x = np.arange(len(TEST_LEVELS))
    for ax, (metric, label, _) in zip(axes, METRICS[:2]):
        scale = 100.0 if metric == "collision" else 1.0
        for k, cond in enumerate(conds):
            cells = [table[cond][t][metric] for t in TEST_LEVELS]
            err = [0.0 if c["ci95"] is None else c["ci95"] * scale for c in cells]
            ax.errorbar(x + (k - (len(conds) - 1) / 2) * 0.06, [c["mean"] * scale for c in cells], yerr=err,
                        marker="o", ms=4, capsize=3, label=cond)  # fmt: skip
        ax.set_xticks(x, TEST_LEVELS)
        ax.set_xlabel("tested on")
        ax.set_ylabel(label + (" [%]" if metric == "collision" else ""))
        if metric == "collision":  # a t interval over few seeds can reach past 0 and 100 %
            ax.set_ylim(-5, 105)
        ax.set_title(f"{label}: mean over training seeds ± 95 % CI")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{ENV_ID['value']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "fog_effect.png")
    plt.close(fig)


def _monitor_rows(path: Path) -> np.ndarray:
    """(episodes, 3) array of return, length, time of a VecMonitor CSV (empty when no episode finished)."""
    lines = path.read_text().splitlines()[2:] if path.stat().st_size else []
    return np.array([[float(v) for v in line.split(",")[:3]] for line in lines if line.strip()]).reshape(-1, 3)


def _episode_curves(out: Path, cond: str, seed: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(cumulative steps, trailing moving average of the episode returns over ≥ 10 episodes) of one agent from its
    VecMonitor logs."""
    files = sorted((out / "monitor").glob(f"{cond}_s{seed}_*.monitor.csv"))
    rows = [r for r in (_monitor_rows(f) for f in files) if r.size]
    if not rows:
        return None
    data = np.concatenate(rows)  # r, l, t per episode
    k = min(max(10, len(data) // 40), len(data))  # about 40 windows over the run, at least 10 episodes each
    return np.cumsum(data[:, 1])[k - 1 :], np.convolve(data[:, 0], np.ones(k) / k, mode="valid")


def learning_curves(out: Path, conditions: list[str], seeds: list[int]) -> None:
    """``curves.png`` (every condition: mean over seeds of the moving-average return) and ``curves/<condition>.png``
    (each training seed and their mean), episode return against training steps (VecMonitor logs)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    (out / "curves").mkdir(exist_ok=True)
    fig, ax = plt.subplots(figsize=(7, 4), dpi=120)
    for cond in conditions:
        curves = [c for c in (_episode_curves(out, cond, seed) for seed in seeds) if c is not None]
        if not curves:
            continue
        end = min(c[0][-1] for c in curves)
        grid = np.linspace(0, end, 50)
        mean = np.mean([np.interp(grid, steps, ret) for steps, ret in curves], axis=0)
        ax.plot(grid, mean, label=cond)
        f2, a2 = plt.subplots(figsize=(6, 3.5), dpi=120)
        for seed, (steps, ret) in zip(seeds, curves):
            a2.plot(steps, ret, lw=0.8, alpha=0.6, label=f"seed {seed}")
        a2.plot(grid, mean, color="k", lw=2, label="mean")
        a2.set_xlabel("training steps")
        a2.set_ylabel("episode return (moving average)")
        a2.set_title(f"{ENV_ID['value']}: trained {cond}")
        a2.legend(fontsize=7)
        f2.tight_layout()
        f2.savefig(out / "curves" / f"{cond}.png")
        plt.close(f2)
    ax.set_xlabel("training steps")
    ax.set_ylabel("episode return (moving average)")
    ax.legend()
    ax.set_title(f"{ENV_ID['value']} learning curves")
    fig.tight_layout()
    fig.savefig(out / "curves.png")
    plt.close(fig)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="rl_benchmark.py", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--env", choices=ENVS, default=ENVS[0],
                   help="the task: FogDriveRL-v0 (default) or FogDriveRLHazard-v0 (stalled vehicles ahead)")
    p.add_argument("--conditions", nargs="+", choices=CONDITIONS, default=list(CONDITIONS),
                   help="training conditions (default: all)")
    p.add_argument("--seeds", type=int, default=1, help="training seeds per condition (default 1; a study: >= 3)")
    p.add_argument("--steps", type=int, default=2048, help="training steps per agent (default 2048; a study: >= 50000)")
    p.add_argument("--episodes", type=int, default=8, help="evaluation episodes per agent and test fog (default 8; a study: >= 32)")
    p.add_argument("--envs", type=int, default=os.cpu_count() or 1, help="subprocess envs (default: the CPU count)")
    p.add_argument("--device", default="auto", help="PPO device: auto (GPU when present), cpu or cuda")
    p.add_argument("--torch-threads", type=int, default=None,
                   help="torch threads for PPO on the CPU (default: 1 with subprocess envs, else torch's own)")
    p.add_argument("--checkpoint", type=int, default=10_000, help="checkpoint every N steps (default 10000)")
    p.add_argument("--episode-seconds", type=float, default=20.0,
                   help="episode length in seconds (default 20, FogDriveRL-v0's; shorter only for smoke runs)")
    p.add_argument("--out", type=Path, default=Path("out/rl_bench"), help="output folder (default out/rl_bench)")
    return p


def main(argv: list[str] | None = None) -> int:
    from tqdm import tqdm

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.steps < 64 or args.episodes < 1 or args.envs < 1 or args.checkpoint < 1:
        parser.error("--seeds, --episodes, --envs and --checkpoint must be >= 1 and --steps >= 64")
    if not 0 < args.episode_seconds < 1e4:
        parser.error("--episode-seconds must be > 0")
    if args.torch_threads is not None and args.torch_threads < 1:
        parser.error("--torch-threads must be >= 1")
    EPISODE_SECONDS["value"] = args.episode_seconds
    ENV_ID["value"] = args.env
    threads = args.torch_threads or (1 if args.envs > 1 else None)
    if threads is not None:
        import torch

        if args.device == "cpu" or not torch.cuda.is_available():
            torch.set_num_threads(threads)  # the env workers need the cores; more threads only spin against them
    args.out.mkdir(parents=True, exist_ok=True)
    study = {"env": args.env, "steps": args.steps, "episode_seconds": args.episode_seconds}
    marker = args.out / "study.json"
    if marker.exists() and json.loads(marker.read_text()) != study:
        parser.error(f"{args.out} holds a study of {marker.read_text().strip()}; this run asks for {json.dumps(study)}: "
                     "use another --out")  # fmt: skip
    marker.write_text(json.dumps(study))
    seeds = list(range(args.seeds))
    # seed-major: after each round of seeds every condition has the same number of finished agents, so an
    # interrupted study can already be evaluated with a smaller --seeds on the same --out
    agents = [(c, s) for s in seeds for c in args.conditions]
    t0 = time.perf_counter()
    for k, (cond, seed) in enumerate(agents):
        elapsed = time.perf_counter() - t0
        eta = "" if not k else f", ETA for training {elapsed / k * (len(agents) - k) / 60:.0f} min"
        print(f"[{k + 1}/{len(agents)}] training {cond} seed {seed}{eta}")
        train(cond, seed, args.steps, args.out, args.envs, args.device, args.checkpoint)
    evals = args.out / "eval"
    evals.mkdir(exist_ok=True)
    results: dict = {}
    cells = [(c, s, t) for c, s in agents for t in TEST_LEVELS]
    for cond, seed, test in tqdm(cells, desc="evaluating", unit="cell"):
        path = evals / f"{cond}_s{seed}_{test}_{args.episodes}.json"
        if not path.exists():
            t_eval = time.perf_counter()
            r = evaluate(args.out / "models" / f"{cond}_s{seed}.zip", test, args.episodes, args.envs, args.device)
            r["wall_s"] = time.perf_counter() - t_eval
            tmp = path.with_name(f".{path.name}.tmp")
            tmp.write_text(json.dumps(r))
            os.replace(tmp, path)
        results.setdefault(cond, {}).setdefault(test, {})[seed] = json.loads(path.read_text())
    table = aggregate(results)
    meta = {"env": args.env, "seeds": args.seeds, "steps": args.steps, "episodes": args.episodes, "envs": args.envs,
            "conditions": args.conditions, "wall_s": time.perf_counter() - t0}  # fmt: skip
    times = wall_times(args.out, args.conditions, seeds, args.episodes)
    (args.out / "matrix.json").write_text(json.dumps({"meta": meta, "table": table, "wall_times": times}, indent=1))
    (args.out / "matrix.md").write_text(render_matrix(table, meta) + "\n\n" + "\n".join(render_wall_times(times)) + "\n")
    figures(table, args.out)
    learning_curves(args.out, args.conditions, seeds)
    print((args.out / "matrix.md").read_text())
    print(f"wrote {args.out / 'matrix.md'}, heatmap.png, fog_effect.png, curves.png in {(time.perf_counter() - t0) / 60:.1f} min")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
