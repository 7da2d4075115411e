"""Do agents slow down before a wall of fog? The fog-bank study (``fog-gym bank-study`` =
``python -m fog_gym.experiments.bank_study``).

Agents learn the hazard task on perceived objects (``"lanes"`` layout, flat: the observation of
``FogDriveRLObjects-v0``, from the camera and the LiDAR — the radar sees through fog) under one of three training
conditions, then drive
``FogDriveRLFogBank-v0`` (a bank on the road ahead, drawn per episode, :class:`~fog_gym.fog.banks.BankConfig`):

* ``homogeneous``: the hazard task in homogeneous fog, a level drawn per episode (clear, light, moderate, dense:
  ``MixedSampler``) — agents that know fog but never met a bank;
* ``banks``: ``FogDriveRLFogBank-v0`` itself;
* ``bank-curriculum``: ``FogDriveRLFogBank-v0`` with thin banks first: the banks' visibility range slides from
  (160, 200) m to the test's (25, 80) m over the first 60 % of training, linearly in extinction.

Every agent is PPO (Stable-Baselines3, ``MlpPolicy``, the RL benchmark's settings) on fog-gym's native vector env.
The evaluation drives ``episodes`` episodes of ``FogDriveRLFogBank-v0`` (seeds 10⁶ + k, disjoint from training's)
with the deterministic policy and measures, per episode: the return, a collision, whether it happened inside the
bank, and the ego's speed 100 m before the bank's near face (``v_before``) and at the face (``v_entry``: the first
frame at or past it; ``info["fog_u"]`` is the ego's distance along the bank's axis). "Slowed" means
``v_entry ≤ v_before − 2.5 m/s``. The scripted detection driver (:class:`~fog_gym.perception.driver.DetectionDriver`)
drives the same episodes twice: with the reach its sensors have in clear air (it enters the bank at speed) and with
their reach in 50 m fog (it drives slowly throughout) — the bounds an agent on this observation lies between.

Units (the study runner, :mod:`fog_gym.experiments.runner`: resume, seeds, ``--jobs``): ``train/<condition>_s<seed>``
(the model, ``models/<name>.zip``; a unit cut short continues from its last checkpoint, every ``--checkpoint``
steps), ``eval/<condition>_s<seed>`` and
``driver/<reach>`` (the agents' camera+lidar set) and ``driver/<sensors>-<reach>`` (the others). The report: ``bank_study.md``, ``bank_study.json`` and ``bank_study.png`` (speed against the
distance to the bank's face, per condition, and the collision rates).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fog_gym.experiments.runner import Report, Study, Unit, aggregate, fmt_stat

CONDITIONS = ("homogeneous", "banks", "bank-curriculum")
#: The perceived-objects observation every agent learns on (FogDriveRLObjects-v0's, from the camera and the LiDAR: the
#: radar sees through fog, so with it the fog would hardly matter) and the env kwargs of the test.
SENSORS = ("camera", "lidar")
#: The scripted driver's sensor sets (its bound per set; the agents' set, camera+lidar, has the keys "clear" and "fog").
DRIVER_SETS = {"camera+lidar": SENSORS, "camera": ("camera",), "lidar": ("lidar",), "radar": ("radar",),
               "fused": ("camera", "lidar", "radar")}  # fmt: skip
OBJECTS = {"observation": "objects", "layout": "lanes", "flat": True, "sensors": list(SENSORS)}
EVAL_SEED = 1_000_000
#: Distances to the bank's face [m] at which the speed profile is read (negative: before it).
PROFILE_U = np.arange(-200.0, 101.0, 10.0)
#: The bank-curriculum's start and end visibility ranges [m] and the share of training it takes.
CURRICULUM = ((160.0, 200.0), (25.0, 80.0), 0.6)


def curriculum_banks(progress: float) -> Any:
    """The bank-curriculum's :class:`~fog_gym.fog.banks.BankConfig` at training ``progress`` ∈ [0, 1]: each end of the
    visibility range slides from the start range to the end range, linearly in extinction (1/visibility).

    >>> curriculum_banks(0.0).visibility, curriculum_banks(1.0).visibility
    ((160.0, 200.0), (25.0, 80.0))
    """
    from fog_gym.fog.banks import BankConfig

    (a0, b0), (a1, b1), share = CURRICULUM
    p = min(max(progress / share, 0.0), 1.0)
    lo, hi = (1.0 / ((1 - p) / x0 + p / x1) for x0, x1 in ((a0, a1), (b0, b1)))
    return BankConfig(visibility=(min(lo, hi), max(lo, hi)))


def episode_measures(speeds: Sequence[float], us: Sequence[float], start: float, length: float, crashed: bool,
                     total: float) -> dict[str, Any]:  # fmt: skip
    """One evaluation episode's measures from its per-frame speeds [m/s] and distances along the bank's axis [m]:
    ``return``, ``collision``, ``crash_in_bank``, ``v_before`` (100 m before the face), ``v_entry`` (at the face;
    None where the episode ended before reaching it) and the speed profile on :data:`PROFILE_U` (None past the end).

    >>> m = episode_measures([25.0, 25.0, 20.0, 10.0], [0.0, 60.0, 120.0, 160.0], 150.0, 100.0, False, 3.0)
    >>> m["v_before"], m["v_entry"], m["slowed"]
    (25.0, 10.0, True)
    """
    u = np.asarray(us, float) - start
    v = np.asarray(speeds, float)

    def at(x: float) -> float | None:
        k = np.flatnonzero(u >= x)
        return float(v[k[0]]) if len(k) else None

    before, entry = at(-100.0), at(0.0)
    profile = [at(x) for x in PROFILE_U]
    inside = bool(crashed and len(u) and 0.0 <= u[-1] <= length)
    slowed = None if before is None or entry is None else bool(entry <= before - 2.5)
    return {"return": float(total), "collision": bool(crashed), "crash_in_bank": inside, "v_before": before,
            "v_entry": entry, "slowed": slowed, "profile": profile}  # fmt: skip


class BankStudy(Study):
    """The fog-bank study (module docstring)."""

    name = "bank-study"
    command = "fog-gym bank-study"
    description = ("Do agents slow down before a wall of fog? Agents on the camera and LiDAR's perceived objects learn "
                   "the hazard task in homogeneous fog, in fog banks or on a curriculum of banks, then drive "
                   "FogDriveRLFogBank-v0; the report gives their speed before and at the bank's face, their collisions "
                   "inside it, and the scripted detection driver's bounds.")  # fmt: skip
    default_out = Path("out/bank_study")
    smoke_help = "2 000 training steps and 2 episodes per agent: checks the pipeline, measures nothing"

    def __init__(self, steps: int = 150_000, envs: int = 8, episodes: int = 32,
                 conditions: Sequence[str] = CONDITIONS, checkpoint: int = 25_000) -> None:  # fmt: skip
        for name, value, low in (("steps", steps, 256), ("envs", envs, 1), ("episodes", episodes, 1),
                                 ("checkpoint", checkpoint, 1)):  # fmt: skip
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
        bad = [c for c in conditions if c not in CONDITIONS]
        if bad or not conditions or len(set(conditions)) < len(conditions):
            raise ValueError(f"conditions must be distinct names of {CONDITIONS}, got {list(conditions)}")
        self.steps, self.envs, self.episodes, self.conditions = steps, envs, episodes, tuple(conditions)
        self.checkpoint = checkpoint  # (not a setting: how often a training unit saves what it has)

    def settings(self) -> dict[str, Any]:
        return {"steps": self.steps, "envs": self.envs, "episodes": self.episodes, "algo": "PPO",
                "observation": OBJECTS, "curriculum": CURRICULUM}  # fmt: skip

    def units(self, seeds: Sequence[int]) -> list[Unit]:
        out = [Unit("train", f"{c}_s{s}", s, {"condition": c}) for s in seeds for c in self.conditions]
        out += [Unit("eval", f"{c}_s{s}", s, {"condition": c}) for s in seeds for c in self.conditions]
        out += [Unit("driver", reach, 0, {"reach": reach}) for reach in ("clear", "fog")]
        out += [Unit("driver", f"{name}-{reach}", 0, {"reach": reach, "sensors": name})
                for name in DRIVER_SETS if name != "camera+lidar" for reach in ("clear", "fog")]  # fmt: skip
        return out

    def artefacts(self, unit: Unit) -> list[str]:
        return [f"models/{unit.key}.zip"] if unit.stage == "train" else []

    def run_unit(self, unit: Unit, out: Path, progress: bool) -> dict[str, Any]:
        if unit.stage == "train":
            return self._train(unit, out, progress)
        if unit.stage == "eval":
            from stable_baselines3 import PPO

            model = PPO.load(str(out / "models" / f"{unit.key}.zip"), device="cpu")
            return self._evaluate(lambda obs: int(model.predict(obs, deterministic=True)[0]), progress)
        return self._driver(unit.params["reach"], unit.params.get("sensors", "camera+lidar"), progress)

    # -- units ------------------------------------------------------------------------------------------------
    def _train(self, unit: Unit, out: Path, progress: bool) -> dict[str, Any]:
        import os
        import pickle
        import time

        import gymnasium as gym
        import torch
        from stable_baselines3 import PPO
        from stable_baselines3.common.callbacks import BaseCallback
        from stable_baselines3.common.vec_env import VecMonitor

        import fog_gym  # noqa: F401
        from fog_gym.experiments.rl_bench.train import new_model
        from fog_gym.experiments.runner import write_atomic
        from fog_gym.fog.schedules import MixedSampler
        from fog_gym.rl.sb3 import VecFogCurriculum, VectorEnvAdapter

        torch.set_num_threads(1)
        condition = unit.params["condition"]
        ckpt = out / "checkpoints" / unit.key  # a unit cut short continues from its last checkpoint
        ckpt.mkdir(parents=True, exist_ok=True)
        model_path, state_path = ckpt / "model.zip", ckpt / "state.pkl"
        state = pickle.loads(state_path.read_bytes()) if model_path.exists() and state_path.exists() else {}
        env_id = "FogDriveRLHazard-v0" if condition == "homogeneous" else "FogDriveRLFogBank-v0"
        kwargs = dict(OBJECTS) if condition != "bank-curriculum" else {**OBJECTS, "banks": curriculum_banks(0.0)}
        base = gym.make_vec(env_id, num_envs=self.envs, vectorization_mode="vector_entry_point", info_detections=False,
                            **kwargs)  # fmt: skip
        venv = VectorEnvAdapter(base)
        venv.seed(1000 * unit.seed + state.get("checkpoints", 0))  # (a resumed run: fresh episodes)
        curriculum = None
        if condition == "homogeneous":
            venv = curriculum = VecFogCurriculum(venv, state.get("curriculum") or MixedSampler(seed=unit.seed))
        venv = VecMonitor(venv)
        worlds, steps, every = base.unwrapped.worlds, self.steps, self.checkpoint
        if state:
            model = PPO.load(str(model_path), env=venv, device="cpu")
        else:
            model = new_model("PPO", "MlpPolicy", venv, steps, self.envs, unit.seed, "cpu", None)

        class Progress(BaseCallback):
            def _on_step(self) -> bool:
                if condition == "bank-curriculum":
                    worlds.banks = curriculum_banks(self.num_timesteps / steps)
                if self.num_timesteps % every < self.training_env.num_envs:
                    self.model.save(str(ckpt / ".model.tmp.zip"))
                    os.replace(ckpt / ".model.tmp.zip", model_path)
                    write_atomic(state_path, pickle.dumps({"checkpoints": state.get("checkpoints", 0) + 1,
                                                           "curriculum": curriculum and curriculum.curriculum}))
                return True

        remaining = steps - model.num_timesteps
        t0 = time.perf_counter()
        if remaining > 0:
            model.learn(remaining, callback=Progress(), reset_num_timesteps=False, progress_bar=progress)
        (out / "models").mkdir(parents=True, exist_ok=True)
        model.save(str(out / "models" / f".{unit.key}.tmp.zip"))
        os.replace(out / "models" / f".{unit.key}.tmp.zip", out / "models" / f"{unit.key}.zip")
        venv.close()
        return {"steps": steps, "trained": max(remaining, 0),
                "steps_per_s": max(remaining, 0) / max(time.perf_counter() - t0, 1e-9)}  # fmt: skip

    def _episodes(self, act, progress: bool, make_kwargs: dict[str, Any] | None = None) -> list[dict[str, Any]]:
        import gymnasium as gym
        from tqdm import tqdm

        import fog_gym  # noqa: F401

        env = gym.make("FogDriveRLFogBank-v0", **{**OBJECTS, **(make_kwargs or {})})
        rows = []
        for k in tqdm(range(self.episodes), desc="episodes", unit="episode", disable=not progress, leave=False):
            obs, info = env.reset(seed=EVAL_SEED + k)
            bank, total, done = info["fog"], 0.0, False
            speeds, us = [info["speed"]], [info["fog_u"]]
            while not done:
                obs, r, term, trunc, info = env.step(act(obs))
                total += r
                speeds.append(info["speed"])
                us.append(info["fog_u"])
                done = term or trunc
            rows.append(episode_measures(speeds, us, bank["start"], bank["length"], info["crashed"], total))
        env.close()
        return rows

    def _evaluate(self, act, progress: bool) -> dict[str, Any]:
        return {"episodes": self._episodes(act, progress)}

    def _driver(self, reach: str, sensors: str, progress: bool) -> dict[str, Any]:
        from fog_gym.perception.driver import DetectionDriver, sensor_reach

        fog = "clear" if reach == "clear" else 50.0
        metres = sensor_reach(DRIVER_SETS[sensors], fog, episodes=4 if self.episodes < 8 else 8)
        driver = DetectionDriver(metres)
        rows = self._episodes(driver.act, progress, {"layout": "list", "flat": False,  # (the driver reads the list)
                                                     "sensors": list(DRIVER_SETS[sensors])})  # fmt: skip
        return {"reach_m": metres, "cruise": driver.cruise, "episodes": rows}

    # -- report -----------------------------------------------------------------------------------------------
    def report(self, records: dict[str, dict[str, Any]], out: Path, seeds: Sequence[int]) -> Report:
        def summary(episodes: list[dict[str, Any]]) -> dict[str, float | None]:
            def mean(key: str, rows: list[dict[str, Any]] | None = None) -> float | None:
                vals = [float(e[key]) for e in (rows if rows is not None else episodes) if e[key] is not None]
                return float(np.mean(vals)) if vals else None

            reached = [e for e in episodes if e["v_entry"] is not None]
            return {"return": mean("return"), "collisions": mean("collision"), "crash_in_bank": mean("crash_in_bank"),
                    "reached": len(reached) / max(len(episodes), 1), "v_before": mean("v_before", reached),
                    "v_entry": mean("v_entry", reached), "slowed": mean("slowed", reached),
                    "dv": (mean("v_entry", reached) - mean("v_before", reached)) if reached else None}  # fmt: skip

        cells: dict[str, dict[str, dict[int, dict[str, Any]]]] = {}
        profiles: dict[str, list[list[float | None]]] = {}
        for key, rec in records.items():
            if rec["stage"] != "eval":
                continue
            cond = rec["params"]["condition"]
            eps = rec["result"]["episodes"]
            known = {k: v for k, v in summary(eps).items() if v is not None}  # (a seed without a metric: not counted)
            cells.setdefault(cond, {}).setdefault("test", {})[rec["seed"]] = known
            profiles.setdefault(cond, []).extend(e["profile"] for e in eps)
        every = {(r["params"].get("sensors", "camera+lidar"), r["params"]["reach"]): r["result"]
                 for r in records.values() if r["stage"] == "driver"}  # fmt: skip
        drivers = {reach: res for (name, reach), res in every.items() if name == "camera+lidar"}
        stats = aggregate(cells, ("return", "collisions", "crash_in_bank", "reached", "v_before", "v_entry", "slowed",
                                  "dv"))  # fmt: skip
        cols = ["return", "collisions", "crash_in_bank", "reached", "v_before", "v_entry", "dv", "slowed"]
        lines = [f"# Fog banks: do agents slow down before the wall? ({len(seeds)} seeds, {self.steps} steps, "
                 f"{self.episodes} test episodes each)", "",
                 "| condition | " + " | ".join(cols) + " |", "|---|" + "---|" * len(cols)]  # fmt: skip
        for cond in self.conditions:
            st = stats.get(cond, {}).get("test", {})
            lines.append(f"| {cond} | " + " | ".join(fmt_stat(st[c], "{:.2f}") if c in st else "–" for c in cols)
                         + " |")  # fmt: skip
        for reach, res in sorted(drivers.items()):
            s = summary(res["episodes"])
            lines.append(f"| driver, {reach} reach ({res['reach_m']:.0f} m, cruise {res['cruise']:.0f} m/s) | "
                         + " | ".join("–" if s[c] is None else f"{s[c]:.2f}" for c in cols) + " |")  # fmt: skip
        others = sorted(k for k in every if k[0] != "camera+lidar")
        if others:
            lines += ["", "The scripted detection driver per sensor set (its reach in clear air and in 50 m fog):", "",
                      "| sensors | reach | reach [m] | cruise [m/s] | " + " | ".join(cols) + " |",
                      "|---|---|---|---|" + "---|" * len(cols)]  # fmt: skip
            for name, reach in sorted(every):
                res, sm = every[(name, reach)], summary(every[(name, reach)]["episodes"])
                lines.append(f"| {name} | {reach} | {res['reach_m']:.0f} | {res['cruise']:.0f} | "
                             + " | ".join("–" if sm[c] is None else f"{sm[c]:.2f}" for c in cols) + " |")  # fmt: skip
        lines += ["", "v_before: speed 100 m before the bank's face; v_entry: at the face [m/s]; dv = v_entry − "
                  "v_before; slowed: share of episodes with dv ≤ −2.5 m/s; reached: share of episodes that reached "
                  "the face; crash_in_bank: share of episodes that ended in a collision inside the bank. Means over "
                  "seeds with the 95 % interval across seeds."]  # fmt: skip

        def figure(path: Path) -> None:
            import matplotlib

            matplotlib.use("Agg")
            import matplotlib.pyplot as plt

            from fog_gym.experiments.runner import save_figure

            fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4))
            named = {**{c: p for c, p in profiles.items()},
                     **{f"driver ({r} reach)": [e["profile"] for e in d["episodes"]] for r, d in drivers.items()}}
            for name, rows in named.items():
                arr = np.array([[np.nan if v is None else v for v in row] for row in rows], float)
                if arr.size:
                    ax.plot(PROFILE_U, np.nanmean(arr, axis=0), label=name)
            ax.axvline(0.0, color="grey", lw=0.8)
            ax.set(xlabel="distance to the bank's near face [m]", ylabel="mean speed [m/s]",
                   title="speed approaching the bank")  # fmt: skip
            ax.legend(fontsize=8)
            conds = [c for c in self.conditions if c in stats]
            for i, key in enumerate(("collisions", "crash_in_bank")):
                vals = [stats[c]["test"][key]["mean"] for c in conds]
                errs = [stats[c]["test"][key]["ci95"] or 0.0 for c in conds]
                bx.bar(np.arange(len(conds)) + 0.4 * i, vals, 0.4, yerr=errs, label=key)
            bx.set_xticks(np.arange(len(conds)) + 0.2, conds)
            bx.set(ylabel="share of test episodes", title="collisions (all, inside the bank)")
            bx.legend(fontsize=8)
            save_figure(fig, path)
            plt.close(fig)

        data = {"stats": stats, "drivers": {f"{n}/{r}": {**summary(d["episodes"]), "reach_m": d["reach_m"],
                                                        "cruise": d["cruise"]} for (n, r), d in every.items()}}  # fmt: skip
        return Report("\n".join(lines) + "\n", data, "bank_study.md", "bank_study.json",
                      {"bank_study.png": figure} if cells else {})

    def describe(self, unit: Unit, result: dict[str, Any]) -> str:
        if unit.stage == "train":
            return f"trained {unit.key}: {result['steps_per_s']:.0f} steps/s"
        eps = result["episodes"]
        return f"{unit.stage} {unit.key}: collisions {np.mean([e['collision'] for e in eps]):.2f}"

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--steps", type=int, default=150_000, help="training steps per agent (default 150000)")
        parser.add_argument("--envs", type=int, default=8, help="worlds of the native vector env (default 8)")
        parser.add_argument("--episodes", type=int, default=32, help="test episodes per agent (default 32)")
        parser.add_argument("--conditions", nargs="+", default=list(CONDITIONS), choices=CONDITIONS,
                            help="training conditions (default all)")  # fmt: skip
        parser.add_argument("--checkpoint", type=int, default=25_000,
                            help="a training unit saves its model every this many steps; a unit cut short continues "
                            "from there (default 25000)")  # fmt: skip

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> BankStudy:
        if args.smoke:
            return cls(steps=2_000, envs=2, episodes=2, conditions=tuple(args.conditions), checkpoint=1_000)
        return cls(args.steps, args.envs, args.episodes, tuple(args.conditions), args.checkpoint)


def main(argv: Sequence[str] | None = None) -> int:
    from fog_gym.experiments.runner import main as run_main

    return run_main(BankStudy, argv)


if __name__ == "__main__":
    raise SystemExit(main())

