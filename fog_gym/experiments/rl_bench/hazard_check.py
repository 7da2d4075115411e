"""How much seeing decides FogDriveRLHazard-v0: scripted drivers and the bird's-eye image's sight distance in fog.

1. **Scripted drivers** (no learning, same seeds for all): *blind* drivers that keep their lane at a fixed target
   speed, and *sighted* drivers that know the stalled vehicles (``info["hazards"]``) within a sight distance D and
   change lanes (or slow down when both neighbours are blocked) when one is in their lane. Their return and
   collision rate show what a policy can earn as a function of how far it sees.
2. **Sight distance of the LiDAR bird's-eye image** per fog level: for every stalled vehicle ahead of the ego in
   its lane (±2 m), the largest distance at which at least ``--min-cells`` occupied cells of the observation fall
   inside its footprint (±1 m margin), i.e. how far the observation lets an agent see a stalled vehicle.

Prints Markdown tables and writes them, the raw numbers and a figure to ``--out`` (``hazard_check.md`` / ``.json`` /
``.png``).

Run: python -m fog_gym.experiments.rl_bench.hazard_check --help
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.rl_bench.data import FASTER, IDLE, LANE_LEFT, LANE_RIGHT, SLOWER
from fog_gym.experiments.rl_bench.data import TEST_LEVELS as LEVELS
from fog_gym.experiments.runner import save_figure, write_report
from fog_gym.world.hazards import hazard_rows

TARGET_SPEEDS = (0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0)


def blocked(others: np.ndarray, lateral: float, sight: float, gap: float = 0.0) -> bool:
    """Whether the lane centred ``lateral`` m to the right is blocked for the ego: a vehicle of ``others`` (rows:
    metres ahead, metres right, closing speed [m/s]) it closes in on within ``sight`` m ahead, or any vehicle in the
    gap from 10 m behind to ``gap`` m ahead (for a lane change).

    >>> blocked(np.array([[30.0, 0.1, 25.0]]), 0.0, 40.0), blocked(np.array([[30.0, 4.0, 25.0]]), 0.0, 40.0)
    (True, False)
    >>> blocked(np.array([[50.0, 0.0, 25.0]]), 0.0, 40.0), blocked(np.array([[20.0, 0.0, -3.0]]), 0.0, 40.0)
    (False, False)
    >>> blocked(np.array([[-5.0, 4.0, -3.0]]), 4.0, 40.0, gap=12.0)  # a car beside the ego: no lane change
    True
    """
    if len(others) == 0:
        return False
    ahead, right, closing = others[:, 0], others[:, 1], others[:, 2]
    lane = np.abs(right - lateral) < 2.0
    closing_in = (ahead > 0.0) & (ahead < sight) & (closing > 0.5)
    beside = (ahead > -10.0) & (ahead < gap)
    return bool(np.any(lane & (closing_in | beside)))


def sighted_action(others: np.ndarray, speed: float, sight: float, cruise: float) -> int:
    """A driver that sees every vehicle within ``sight`` m ahead: leave a lane where it closes in on one for a free
    neighbour (left first; lanes beyond the road are blocked), slow down if it cannot, else hold ``cruise`` m/s."""
    if blocked(others, 0.0, sight):
        if not blocked(others, -4.0, sight, gap=12.0):
            return LANE_LEFT
        if not blocked(others, 4.0, sight, gap=12.0):
            return LANE_RIGHT
        return SLOWER
    if speed < cruise - 2.5:
        return FASTER
    if speed > cruise + 2.5:
        return SLOWER
    return IDLE


def safe_speed(sight: float, decel: float = 6.0, react: float = 0.6) -> float:
    """The highest target speed of the ego's grid (0, 5, …, 30 m/s) that stops within 80 % of ``sight`` metres
    (``react`` s, then ``decel`` m/s², about what highway-env's speed controller manages).

    >>> safe_speed(45.0), safe_speed(20.0), safe_speed(5.0)
    (15.0, 10.0, 0.0)
    """
    ok = [v for v in TARGET_SPEEDS if v * react + v * v / (2 * decel) <= 0.8 * sight]
    return max(ok)


def others_ego(base: Any, lanes: int = 3, lane_width: float = 4.0) -> np.ndarray:
    """Every other vehicle as (metres ahead, metres right, closing speed), plus phantom vehicles filling the lanes
    beyond the road's edges (so that a driver never steers off it)."""
    st = base.world.vehicle_state()
    x, y, yaw = base.world.ego_pose
    c, s = np.cos(yaw), np.sin(yaw)
    d = st.centers[1:, :2] - np.array([x, y])
    ahead, right = d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c
    closing = st.velocities[0, 0] * c + st.velocities[0, 1] * s - (st.velocities[1:, 0] * c + st.velocities[1:, 1] * s)
    rows = [np.c_[ahead, right, closing]]
    lane = int(np.floor(y / lane_width + 0.5))  # highway-env's straight road: lane k is centred at y = 4k
    for edge in (-1, lanes):
        rows.append(np.array([[0.0, (edge - lane) * lane_width, 0.0]]))
    return np.concatenate(rows)


def run_driver(kind: str, value: float, episodes: int, seed0: int) -> dict[str, float]:
    """Mean return, collision rate and mean speed of a scripted driver over ``episodes`` seeded episodes."""
    import gymnasium as gym

    import fog_gym  # noqa: F401

    env = gym.make("FogDriveRLHazard-v0", fog="clear")
    base = env.unwrapped
    rets, crashes, speeds = [], [], []
    for k in range(episodes):
        _, info = env.reset(seed=seed0 + k)
        speed, total, sp = 25.0, 0.0, []
        while True:
            if kind == "blind":  # approach the target speed, then hold the lane
                a = FASTER if speed < value - 2.5 else SLOWER if speed > value + 2.5 else IDLE
            else:
                a = sighted_action(others_ego(base), speed, value, safe_speed(value))
            _, r, term, trunc, info = env.step(a)
            total += float(r)
            speed = float(info["speed"])
            sp.append(speed)
            if term or trunc:
                break
        rets.append(total)
        crashes.append(float(info["crashed"]))
        speeds.append(float(np.mean(sp)))
    env.close()
    return {"return": float(np.mean(rets)), "return_sd": float(np.std(rets, ddof=1)) if episodes > 1 else 0.0,
            "collision": float(np.mean(crashes)), "speed": float(np.mean(speeds)), "episodes": episodes}  # fmt: skip


def bev_hits(bev: np.ndarray, ahead: float, right: float, length: float, width: float, bev_ahead: float,
             metres: float = 64.0, sensor_x: float = 0.0) -> int:  # fmt: skip
    """Occupied cells of a (2, S, S) bird's-eye image inside a vehicle's footprint (1 m margin); ``ahead``/``right``
    are the vehicle centre's offsets from the ego centre, ``sensor_x`` the LiDAR's offset ahead of it.

    >>> img = np.zeros((2, 64, 64), np.uint8); img[0, 10, 32] = 255  # cell centre: 21.5 m ahead, 0.5 m right
    >>> bev_hits(img, 21.0, 0.0, 4.5, 1.9, 0.0), bev_hits(img, 40.0, 0.0, 4.5, 1.9, 0.0)
    (1, 0)
    """
    size = bev.shape[1]
    cell = metres / size
    x = metres / 2 + bev_ahead - (np.arange(size) + 0.5) * cell  # row centres: metres ahead of the sensor
    y = (np.arange(size) + 0.5) * cell - metres / 2  # column centres: metres to the right
    rows = np.abs(x - (ahead - sensor_x)) <= length / 2 + 1.0
    cols = np.abs(y - right) <= width / 2 + 1.0
    return int(np.count_nonzero(bev[0][np.ix_(rows, cols)]))


def sight_distances(level: str, episodes: int, seed0: int, min_cells: int) -> list[float]:
    """Per approached stalled vehicle (ego lane, ahead), the largest distance at which the observation shows it."""
    import gymnasium as gym

    import fog_gym  # noqa: F401
    from fog_gym.envs.presets import HAZARD_BEV_AHEAD

    env = gym.make("FogDriveRLHazard-v0", fog=level)
    base = env.unwrapped
    lidar = base.config.rig.lidar
    sensor_x = float(lidar.pose.x)
    out: list[float] = []
    for k in range(episodes):
        obs, info = env.reset(seed=seed0 + k)
        seen: dict[int, float] = {}
        approached: set[int] = set()
        while True:
            hz = hazard_rows(info)
            for i, (a, r, length, width) in enumerate(hz):
                if abs(r) < 2.0 and 0.0 < a < 56.0:
                    approached.add(i)
                    if bev_hits(obs["LIDAR_BEV"], a, r, length, width, HAZARD_BEV_AHEAD, sensor_x=sensor_x) >= min_cells:
                        seen[i] = max(seen.get(i, 0.0), float(a))
            # a lane keeper at 15 m/s: slow enough to reach the stalled vehicles that lie in its lane
            speed = float(info["speed"])
            near = [a for a, r, *_ in hz if abs(r) < 2.0 and 0.0 < a < 20.0]
            act = LANE_LEFT if near else (FASTER if speed < 12.5 else SLOWER if speed > 17.5 else IDLE)
            obs, _, term, trunc, info = env.step(act)
            if term or trunc:
                break
        out += [seen.get(i, 0.0) for i in sorted(approached)]
    env.close()
    return out


def figure(results: dict[str, Any], path: Path) -> None:
    """Left: return of the blind and sighted drivers; right: sight distance of the bird's-eye image per fog."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 3.8), dpi=120)
    names = list(results["drivers"])
    ret = [results["drivers"][n]["return"] for n in names]
    sd = [results["drivers"][n]["return_sd"] for n in names]
    col = [results["drivers"][n]["collision"] for n in names]
    labels = [f"blind\n{n.split()[1]} m/s" if n.startswith("blind") else f"sees\n{n.split()[1]} m" for n in names]
    bars = a.bar(range(len(names)), ret, yerr=sd, color=["#999" if n.startswith("blind") else "#2a7" for n in names])
    for bar, c in zip(bars, col):
        a.text(bar.get_x() + bar.get_width() / 2, 1, f"{c:.0%}", ha="center", va="bottom", fontsize=7, color="w")
    a.set_xticks(range(len(names)), labels, fontsize=7)
    a.set_ylabel("episode return (bar label: collision rate)")
    a.set_title("scripted drivers, clear air")
    levels = list(results["sight"])
    b.boxplot([results["sight"][k] or [0.0] for k in levels], tick_labels=levels)
    b.set_ylabel("distance at which a stalled vehicle shows [m]")
    b.set_title("LiDAR bird's-eye image: sight per fog level")
    fig.suptitle("FogDriveRLHazard-v0: what seeing is worth, and how far the observation sees", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m fog_gym.experiments.rl_bench.hazard_check", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--episodes", type=int, default=20, help="episodes per driver and per fog level (default 20)")
    p.add_argument("--speeds", type=float, nargs="+", default=[10.0, 15.0, 20.0, 25.0],
                   help="blind drivers' target speeds [m/s] (default 10 15 20 25)")
    p.add_argument("--sights", type=float, nargs="+", default=[10.0, 20.0, 30.0, 45.0],
                   help="sighted drivers' sight distances [m] (default 10 20 30 45)")
    p.add_argument("--min-cells", type=int, default=2, help="occupied cells that count as seeing a vehicle (default 2)")
    p.add_argument("--seed", type=int, default=2_000_000, help="first episode seed (default 2000000)")
    p.add_argument("--out", type=Path, default=Path("out/rl_hazard"), help="output folder (default out/rl_hazard)")
    return p


def main(argv: list[str] | None = None) -> int:
    from tqdm import tqdm

    parser = build_parser()
    args = parser.parse_args(argv)
    if args.episodes < 2 or args.min_cells < 1:
        parser.error("--episodes must be >= 2 and --min-cells >= 1")
    if any(not 0 <= v <= 30 for v in args.speeds) or any(not 0 < d <= 56 for d in args.sights):
        parser.error("--speeds must lie in [0, 30] m/s and --sights in (0, 56] m (the bird's-eye image's reach)")
    t0 = time.perf_counter()
    drivers = [("blind", v) for v in args.speeds] + [("sighted", d) for d in args.sights]
    results: dict[str, Any] = {"drivers": {}, "sight": {}}
    for kind, v in tqdm(drivers, desc="scripted drivers", unit="driver", file=sys.stderr):
        results["drivers"][f"{kind} {v:g}"] = run_driver(kind, v, args.episodes, args.seed)
    for level in tqdm(LEVELS, desc="sight distance", unit="fog", file=sys.stderr):
        results["sight"][level] = sight_distances(level, args.episodes, args.seed, args.min_cells)
    lines = ["## Scripted drivers on FogDriveRLHazard-v0", "",
             f"{args.episodes} episodes each (seeds {args.seed}+), clear air.", "",
             "| driver | return (± SD) | collision rate | mean speed [m/s] |", "|---|---|---|---|"]  # fmt: skip
    for name, r in results["drivers"].items():
        label = f"blind, {name.split()[1]} m/s" if name.startswith("blind") else f"sees {name.split()[1]} m ahead, {safe_speed(float(name.split()[1])):g} m/s"
        lines.append(f"| {label} | {r['return']:.1f} ± {r['return_sd']:.1f} | {r['collision']:.0%} | {r['speed']:.1f} |")
    lines += ["", "## How far the LiDAR bird's-eye image shows a stalled vehicle in the ego's lane", "",
              f"Per approached vehicle, the largest distance with ≥ {args.min_cells} occupied cells in its footprint "
              "(0: never shown); the image reaches 56 m ahead of the LiDAR.", "",
              "| fog | vehicles | median [m] | 10th percentile [m] | never shown |", "|---|---|---|---|---|"]  # fmt: skip
    for level, d in results["sight"].items():
        a = np.array(d) if d else np.zeros(1)
        lines.append(f"| {level} | {len(d)} | {np.median(a):.0f} | {np.percentile(a, 10):.0f} | {np.mean(a == 0):.0%} |")
    text = "\n".join(lines)
    write_report(args.out, "hazard_check", text, results)
    figure(results, args.out / "hazard_check.png")
    print(text)
    print(f"\n{time.perf_counter() - t0:.0f} s; wrote {args.out / 'hazard_check.md'}, .json and .png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
