"""Helpers shared by the benchmarks (:mod:`~fog_gym.experiments.bench.env`, ``.sensors``, ``.fog``, ``.dataset`` and
``.suite``, which runs them all): timing, summaries, Markdown tables, the run's metadata and the command-line
options they share. Timings are reported, never asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

DEFAULT_REPEATS = 20
QUICK_REPEATS = 3
WARMUP_STEPS = 2
#: Packed traffic on the ``highway`` town (5 lanes, density 12): ~50 vehicles within the LiDAR's 120 m.
POINT_SENSOR_TRAFFIC = {"vehicles_count": 60, "vehicles_density": 12, "lanes_count": 5}
CHANNEL_LABELS = {"LIDAR_TOP": "LiDAR", "SEM_LIDAR_TOP": "semantic LiDAR", "RADAR_FRONT": "radar"}


def timed(fn: Callable[..., Any], *args: Any, **kwargs: Any) -> tuple[Any, float]:
    """Call ``fn`` and return ``(result, elapsed milliseconds)``."""
    t0 = time.perf_counter_ns()
    out = fn(*args, **kwargs)
    return out, (time.perf_counter_ns() - t0) / 1e6


def summarize(samples: list[float]) -> dict[str, Any]:
    """Return the median, the p25/p75, the min/max and the raw samples (milliseconds)."""
    a = np.asarray(samples, dtype=np.float64)
    if a.size == 0:
        return {"n": 0}
    p25, med, p75 = np.percentile(a, [25, 50, 75])
    return {
        "n": int(a.size), "median": float(med), "p25": float(p25), "p75": float(p75),
        "min": float(a.min()), "max": float(a.max()), "samples": [round(float(x), 4) for x in a],
    }  # fmt: skip


def idle_action(space: Any) -> Any:
    """The idle action of a bare highway-env scenario: IDLE (1) for discrete meta-actions, zeros for continuous
    ones (``FogDriveEnv.idle_action`` is the env's own)."""
    from gymnasium import spaces

    if isinstance(space, spaces.Discrete):
        return 1
    if isinstance(space, spaces.Box):
        return np.zeros(space.shape, space.dtype)
    raise TypeError(f"no idle action for action space {space!r}")


def fmt_ms(stat: dict[str, Any] | None) -> str:
    if not stat or not stat.get("n"):
        return "—"
    med = stat["median"]
    if stat["n"] == 1:
        return f"{med:.2f}"
    return f"{med:.2f} ({stat['p25']:.2f}–{stat['p75']:.2f})"


def markdown_table(header: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(str(c).ljust(w) for c, w in zip(cells, widths)) + " |"

    sep = "|" + "|".join("-" * (w + 2) for w in widths) + "|"
    return "\n".join([line(header), sep, *(line(r) for r in rows)])


def counts_summary(counts: dict[str, list[int]]) -> dict[str, dict[str, float]]:
    """Median, min and max of each non-empty count series."""
    return {k: {"median": float(np.median(v)), "min": int(min(v)), "max": int(max(v))} for k, v in counts.items() if v}


def sensor_tick(env: Any) -> int:
    """The simulation tick that the env's current keyframe closes (the tick its point sensors measured)."""
    return max(env.world.tick - 1, 0)


class EpisodeKeeper:
    """Reset the env (untimed) when an episode ends, and refresh the solo rigs' props caches after a reset."""

    def __init__(self, env: Any, solos: dict[str, Any]) -> None:
        self.env, self.solos = env, solos
        self.resets = 0
        self.steps = 0  # steps since the last reset

    def after_step(self, terminated: bool, truncated: bool = False) -> None:
        self.steps += 1
        if terminated or truncated or self.steps >= self.env.config.episode_steps:
            self.resets += 1
            self.steps = 0
            self.env.reset(seed=self.resets)
            for rig in self.solos.values():  # prop_primitives() is cached per static world: fill it now, untimed
                rig.primitives(self.env.scene)


def load_average() -> list[float] | None:
    """1-, 5- and 15-minute load averages (None where the OS has none). Noise from other processes shows here."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def add_common_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """``--repeats``, ``--quick`` and ``--json``, as every benchmark script takes them."""
    parser.add_argument("--repeats", type=positive_int, default=None,
                        help=f"timed frames per configuration (default {DEFAULT_REPEATS}; {QUICK_REPEATS} with --quick)")
    parser.add_argument("--quick", action="store_true", help=f"smoke run: {QUICK_REPEATS} repeats")
    parser.add_argument("--json", type=Path, default=None, metavar="PATH",
                        help="also write every figure (with the raw samples) as JSON to PATH")  # fmt: skip
    return parser


def repeats_of(args: argparse.Namespace) -> int:
    return args.repeats or (QUICK_REPEATS if args.quick else DEFAULT_REPEATS)


def run_meta(**extra: Any) -> dict[str, Any]:
    """The run's machine and library versions, and the load average at its start."""
    from importlib.metadata import version

    import numba

    import fog_gym.envs.fogdrive  # noqa: F401  (import everything up front: module imports are not env construction)

    return {
        **extra, "cpu_count": os.cpu_count(), "numba": numba.__version__, "numba_threads": numba.get_num_threads(),
        "highway_env": version("highway-env"), "python": platform.python_version(),
        "platform": platform.platform(terse=True), "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "loadavg_start": load_average(),
    }  # fmt: skip


def finish_meta(meta: dict[str, Any], t0: float) -> dict[str, Any]:
    """Add the wall time since ``t0``, the load average at the end and numba's threading layer."""
    import numba

    meta.update(wall_s=time.perf_counter() - t0, loadavg_end=load_average(), numba_layer=numba.threading_layer())
    return meta


def meta_line(meta: dict[str, Any]) -> str:
    return (f"{meta['cpu_count']} CPUs, numba {meta['numba']} ({meta['numba_threads']} threads, "
            f"{meta.get('numba_layer', '?')} layer) · highway-env {meta['highway_env']} · Python {meta['python']} · "
            f"{meta['platform']} · load average at start {meta['loadavg_start']}, at end {meta.get('loadavg_end')}")  # fmt: skip


def write_json(path: Path | None, results: dict[str, Any]) -> None:
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(results, indent=2))
        print(f"\nwrote {path}", file=sys.stderr)


def bench_main(argv: list[str] | None, module: str, doc: str, key: str, bench: Callable[[int, bool], Any],
               render: Callable[[Any, int], list[str]]) -> int:
    """A one-figure bench's command line: the common flags, ``bench(repeats, quick)``, the meta line, the rendered
    table, and ``{"meta": ..., key: results}`` to ``--json``."""
    parser = argparse.ArgumentParser(prog=f"python -m {module}", description=doc.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    add_common_arguments(parser)
    args = parser.parse_args(argv)
    repeats = repeats_of(args)
    meta = run_meta(repeats=repeats, quick=args.quick)
    t0 = time.perf_counter()
    results = bench(repeats, args.quick)
    finish_meta(meta, t0)
    print(meta_line(meta))
    print("\n".join(render(results, repeats)))
    write_json(args.json, {"meta": meta, key: results})
    return 0
