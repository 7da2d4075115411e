"""What trained agents do on FogDriveRLHazard-v0: do they react to the stalled vehicles they could see?

For each agent (a PPO or DQN ``.zip``, e.g. ``<study>/models/clear_s0.zip`` of ``fog-gym rl-bench``) and test fog,
deterministic episodes on seeds disjoint from training and from the benchmark's evaluation (3·10⁶ + k) give:

* **evasive rate near a hazard**: the fraction of steps with a lane change or ``SLOWER`` while a stalled vehicle
  stands in the ego's lane (±2 m) less than ``--near`` metres ahead, against the same fraction on every other step.
  An agent that uses its sensors evades more often when a stalled vehicle is ahead; one that ignores them evades
  at the same rate either way;
* **passed**: stalled vehicles per episode that the ego drove past (from ahead of it to 5 m behind its centre);
* return, collision rate and mean speed, as the benchmark reports them.

Prints a Markdown table and writes it (``probe.md``) and the raw numbers (``probe.json``) to ``--out``.

Run: python -m fog_gym.experiments.rl_bench.probe --help
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.rl_bench.data import LANE_LEFT, LANE_RIGHT, SLOWER
from fog_gym.experiments.rl_bench.data import TEST_LEVELS as LEVELS
from fog_gym.experiments.rl_bench.train import ALGOS
from fog_gym.experiments.runner import write_report
from fog_gym.world.hazards import hazard_rows

EVASIVE = (LANE_LEFT, LANE_RIGHT, SLOWER)
PROBE_SEED = 3_000_000


def hazard_near(hazards: np.ndarray, near: float) -> bool:
    """Whether a stalled vehicle (rows: metres ahead, metres right, length, width) stands in the ego's lane less
    than ``near`` metres ahead.

    >>> hazard_near(np.array([[30.0, 0.5, 4.5, 1.9]]), 40.0), hazard_near(np.array([[30.0, 4.0, 4.5, 1.9]]), 40.0)
    (True, False)
    >>> hazard_near(np.zeros((0, 4)), 40.0)
    False
    """
    if len(hazards) == 0:
        return False
    return bool(np.any((np.abs(hazards[:, 1]) < 2.0) & (hazards[:, 0] > 0.0) & (hazards[:, 0] < near)))


def passed(aheads: np.ndarray) -> int:
    """Stalled vehicles the ego drove past: columns of ``aheads`` (steps × vehicles, metres ahead of the ego) that
    are ahead at some step and more than 5 m behind at a later one.

    >>> passed(np.array([[20.0, 80.0], [2.0, 60.0], [-6.0, 40.0]]))
    1
    >>> passed(np.array([[-8.0], [-9.0]]))  # never ahead: not passed
    0
    """
    n = 0
    for col in np.asarray(aheads, float).T:
        ahead = np.flatnonzero(col > 0.0)
        if len(ahead) and np.any(col[ahead[0] :] < -5.0):
            n += 1
    return n


def probe(model_path: Path, fog: str, episodes: int, near: float, seed0: int = PROBE_SEED,
          algo: str = "PPO") -> dict[str, float]:  # fmt: skip
    """Behaviour of one agent over ``episodes`` deterministic episodes at ``fog`` (see the module docstring)."""
    import gymnasium as gym

    import fog_gym  # noqa: F401
    from fog_gym.experiments.rl_bench.train import algo_class

    model = algo_class(algo).load(model_path, device="cpu")
    env = gym.make("FogDriveRLHazard-v0", fog=fog)
    counts = {"near": [0, 0], "far": [0, 0]}  # evasive steps, steps
    rets, crashes, speeds, passes = [], [], [], []
    for k in range(episodes):
        obs, info = env.reset(seed=seed0 + k)
        total, sp, aheads = 0.0, [], [hazard_rows(info)[:, 0].copy()]
        while True:
            action = int(model.predict(obs, deterministic=True)[0])
            key = "near" if hazard_near(hazard_rows(info), near) else "far"
            counts[key][0] += action in EVASIVE
            counts[key][1] += 1
            obs, r, term, trunc, info = env.step(action)
            total += float(r)
            sp.append(float(info["speed"]))
            aheads.append(hazard_rows(info)[:, 0].copy())
            if term or trunc:
                break
        rets.append(total)
        crashes.append(float(info["crashed"]))
        speeds.append(float(np.mean(sp)))
        passes.append(passed(np.array(aheads)))
    env.close()
    rate = {k: (e / n if n else float("nan")) for k, (e, n) in counts.items()}
    return {"evasive_near": rate["near"], "evasive_far": rate["far"], "steps_near": counts["near"][1],
            "steps_far": counts["far"][1], "passed": float(np.mean(passes)), "return": float(np.mean(rets)),
            "collision": float(np.mean(crashes)), "speed": float(np.mean(speeds)), "episodes": episodes}  # fmt: skip


def summary(results: dict[str, dict[str, Any]]) -> list[str]:
    """Per training condition (agents named ``<condition>_s<seed>``) and fog: the mean over its agents.

    >>> r = {"clear_s0": {"dense": {"evasive_near": 0.5, "evasive_far": 0.1, "passed": 1.0, "collision": 1.0}},
    ...      "clear_s1": {"dense": {"evasive_near": 0.3, "evasive_far": 0.1, "passed": 2.0, "collision": 0.5}}}
    >>> summary(r)[-1]
    '| clear | dense | 2 | 40% / 10% | 1.50 | 75% |'
    """
    groups: dict[str, list[dict[str, Any]]] = {}
    for name, fogs in results.items():
        groups.setdefault(name.rsplit("_s", 1)[0], []).append(fogs)
    lines = ["", "### Mean over each condition's agents", "",
             "| trained on | fog | agents | evasive near / elsewhere | passed per episode | collisions |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for cond, agents in groups.items():
        for fog in agents[0]:
            rows = [a[fog] for a in agents if fog in a]
            m = {k: float(np.nanmean([r[k] for r in rows])) for k in ("evasive_near", "evasive_far", "passed", "collision")}
            lines.append(f"| {cond} | {fog} | {len(rows)} | {m['evasive_near']:.0%} / {m['evasive_far']:.0%} | "
                         f"{m['passed']:.2f} | {m['collision']:.0%} |")  # fmt: skip
    return lines


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m fog_gym.experiments.rl_bench.probe", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("models", type=Path, nargs="+", help="agents (.zip) trained on FogDriveRLHazard-v0")
    p.add_argument("--algo", choices=ALGOS, default="PPO", help="their learner (default PPO)")
    p.add_argument("--fogs", nargs="+", choices=LEVELS, default=list(LEVELS), help="test fog levels (default: all)")
    p.add_argument("--episodes", type=int, default=16, help="episodes per agent and fog (default 16)")
    p.add_argument("--near", type=float, default=40.0, help="a stalled vehicle this close ahead counts (default 40 m)")
    p.add_argument("--out", type=Path, default=Path("out/rl_probe"), help="output folder (default out/rl_probe)")
    return p


def main(argv: list[str] | None = None) -> int:
    from tqdm import tqdm

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.episodes < 1 or not 0 < args.near <= 200:
        parser.error("--episodes must be >= 1 and --near in (0, 200] m")
    missing = [str(m) for m in args.models if not m.is_file()]
    if missing:
        parser.error(f"no such model file: {', '.join(missing)}")
    t0 = time.perf_counter()
    cells = [(m, f) for m in args.models for f in args.fogs]
    results: dict[str, dict[str, Any]] = {}
    for model, fog in tqdm(cells, desc="probing agents", unit="cell", file=sys.stderr):
        results.setdefault(model.stem, {})[fog] = probe(model, fog, args.episodes, args.near, algo=args.algo)
    lines = [f"## What the agents do ({args.episodes} episodes per cell, seeds {PROBE_SEED}+)", "",
             f"Evasive = lane change or SLOWER; near = a stalled vehicle in the ego's lane < {args.near:g} m ahead.", "",
             "| agent | fog | evasive near / elsewhere | steps near | passed per episode | return | collisions | speed [m/s] |",
             "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for name, fogs in results.items():
        for fog, r in fogs.items():
            lines.append(f"| {name} | {fog} | {r['evasive_near']:.0%} / {r['evasive_far']:.0%} | {r['steps_near']} | "
                         f"{r['passed']:.2f} | {r['return']:.1f} | {r['collision']:.0%} | {r['speed']:.1f} |")  # fmt: skip
    lines += summary(results)
    text = "\n".join(lines)
    write_report(args.out, "probe", text, results)
    print(text)
    print(f"\n{time.perf_counter() - t0:.0f} s; wrote {args.out / 'probe.md'} and probe.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
