"""Evaluate each trained agent on clear / light / moderate / dense fog over fixed seeds: the train × test matrix.

Writes ``<out>/matrix.md`` (mean return, collision rate, mean speed, each with a 95 % confidence interval) and
``<out>/matrix.png`` (heatmap of mean return). Needs the ``rl`` extra and the models of
``examples/train_curriculum.py``.

Run: python examples/eval_matrix.py --help
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

TEST_LEVELS = ("clear", "light", "moderate", "dense")
#: Row order of the matrix: the training conditions of examples/train_curriculum.py, then any other model by name.
CONDITION_ORDER = ("clear", "light", "dense", "mixed", "curriculum")


def evaluate(model_path: Path, fog: str, episodes: int, seed: int = 1000) -> dict[str, np.ndarray]:
    import gymnasium as gym
    from stable_baselines3 import PPO

    import fog_gym  # noqa: F401

    model = PPO.load(model_path, device="cpu")
    env = gym.make("FogDriveRL-v0", fog=fog)
    returns, crashes, speeds = [], [], []
    for e in range(episodes):  # the same seeds for every agent and level
        obs, info = env.reset(seed=seed + e)
        total, done, v = 0.0, False, []
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            total += float(reward)
            v.append(info["speed"])
            done = terminated or truncated
        returns.append(total)
        crashes.append(float(info["crashed"]))
        speeds.append(float(np.mean(v)))
    env.close()
    return {"return": np.array(returns), "collision": np.array(crashes), "speed": np.array(speeds)}


def ci95(x: np.ndarray) -> tuple[float, float | None]:
    """Mean and half-width of the normal 95 % CI of the mean; None when one value gives no spread.

    >>> ci95(np.array([1.0, 3.0]))
    (2.0, 1.96)
    >>> ci95(np.array([4.0]))
    (4.0, None)
    """
    if len(x) < 2:
        return float(x.mean()), None
    return float(x.mean()), round(float(1.96 * x.std(ddof=1) / np.sqrt(len(x))), 12)


def cell(x: np.ndarray, fmt: str) -> str:
    """``mean ± CI`` with ``fmt`` for one value (e.g. ``{:.2f}``); ``± n/a`` for a single episode.

    >>> cell(np.array([1.0]), "{:.2f}")
    '1.00 ± n/a'
    """
    mean, half = ci95(x)
    return f"{fmt.format(mean)} ± " + ("n/a" if half is None else fmt.format(half))


def model_order(models: list[Path]) -> list[Path]:
    """Models in condition order (clear, light, dense, mixed, curriculum), others after by name.

    >>> [m.stem for m in model_order([Path("mixed.zip"), Path("clear.zip"), Path("zz.zip"), Path("dense.zip")])]
    ['clear', 'dense', 'mixed', 'zz']
    """
    rank = {c: i for i, c in enumerate(CONDITION_ORDER)}
    return sorted(models, key=lambda m: (rank.get(m.stem, len(rank)), m.stem))


def write_matrix(results: dict[str, dict[str, dict[str, np.ndarray]]], out: Path, episodes: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    agents = list(results)
    lines = [f"# Train × test fog matrix ({episodes} episodes per cell, seeds 1000…{1000 + episodes - 1})", ""]
    for metric, label, fmt in (("return", "mean return", "{:.2f}"), ("collision", "collision rate", "{:.0%}"),
                               ("speed", "mean speed [m/s]", "{:.1f}")):  # fmt: skip
        lines += [f"## {label} (95 % CI)", "", "| trained on \\ tested on | " + " | ".join(TEST_LEVELS) + " |",
                  "|---|" + "---|" * len(TEST_LEVELS)]  # fmt: skip
        for a in agents:
            lines.append(f"| {a} | " + " | ".join(cell(results[a][t][metric], fmt) for t in TEST_LEVELS) + " |")
        lines.append("")
    (out / "matrix.md").write_text("\n".join(lines))
    grid = np.array([[results[a][t]["return"].mean() for t in TEST_LEVELS] for a in agents])
    fig, ax = plt.subplots(figsize=(6, 0.6 * len(agents) + 1.5), dpi=120)
    im = ax.imshow(grid, cmap="viridis")
    ax.set_xticks(range(len(TEST_LEVELS)), TEST_LEVELS)
    ax.set_yticks(range(len(agents)), agents)
    ax.set_xlabel("tested on")
    ax.set_ylabel("trained on")
    for i in range(len(agents)):
        for j in range(len(TEST_LEVELS)):
            ax.text(j, i, f"{grid[i, j]:.1f}", ha="center", va="center", color="w")
    fig.colorbar(im, ax=ax, label="mean return")
    ax.set_title("FogDriveRL-v0: mean return, train × test fog")
    fig.tight_layout()
    fig.savefig(out / "matrix.png")
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    from tqdm import tqdm

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--models", type=Path, default=Path("out/rl/models"), help="folder of <condition>.zip models")
    parser.add_argument("--episodes", type=int, default=5, help="episodes per (agent, level) cell (default 5)")
    parser.add_argument("--out", type=Path, default=Path("out/rl"), help="output folder (default out/rl)")
    args = parser.parse_args(argv)
    models = model_order(list(args.models.glob("*.zip")))
    if not models:
        parser.error(f"no models in {args.models}: run examples/train_curriculum.py first")
    if args.episodes < 1:
        parser.error("--episodes must be >= 1")
    results = {}
    cells = [(m, t) for m in models for t in TEST_LEVELS]
    for m, t in tqdm(cells, desc="evaluating", unit="cell"):
        results.setdefault(m.stem, {})[t] = evaluate(m, t, args.episodes)
    write_matrix(results, args.out, args.episodes)
    print((args.out / "matrix.md").read_text())
    print(f"wrote {args.out / 'matrix.md'} and {args.out / 'matrix.png'}")


if __name__ == "__main__":
    main()
