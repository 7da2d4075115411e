"""The RL benchmark as a study of the runner: its settings (:class:`RLConfig`), its units (one training unit per
condition and seed, one evaluation unit per agent and test fog), its report and its command line.

Units run seed-major: after each round of seeds every condition has the same number of finished agents, so an
interrupted study can already be reported with a smaller ``--seeds`` into the same ``--out``. Resumable twice over:
the runner keeps finished agents and evaluation cells, and a training unit continues from its last checkpoint
(model and the schedule's state, every ``--checkpoint`` steps).
"""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fog_gym.experiments.rl_bench.data import (CONDITIONS, DEFAULT_CONDITIONS, EVAL_SEED, SENSOR_SETS, TEST_LEVELS,
                                              VEC_ENVS, agent_name)  # fmt: skip
from fog_gym.experiments.rl_bench.train import ALGOS
from fog_gym.experiments.runner import Report, Study, Unit, aggregate

#: The documented study's budget (docs/experiments/rl_benchmark.md: 5 training seeds × 2.5·10⁵ steps, 32 evaluation
#: episodes per cell), against which a run's budget line places it.
STUDY_BUDGET = {"seeds": 5, "steps": 250_000, "episodes": 32}


def budget_line(seeds: int, steps: int, episodes: int, agents: int) -> str:
    """What a run is, from its own numbers, against the documented study's budget (:data:`STUDY_BUDGET`).

    >>> budget_line(1, 250_000, 32, 4)
    'Budget: 4 agents (1 training seed) × 250,000 steps, 32 evaluation episodes per cell — a one-seed run: its cells have no interval across training seeds, so no difference between conditions is resolved (the documented study: 5 seeds × 250,000 steps × 32 episodes).'
    >>> budget_line(5, 250_000, 32, 35).split(" — ")[1]
    "a study at the documented study's budget (5 seeds × 250,000 steps × 32 episodes)."
    """
    b = STUDY_BUDGET
    head = (f"Budget: {agents} agents ({seeds} training seed{'s' if seeds != 1 else ''}) × {steps:,} steps, {episodes} "
            f"evaluation episodes per cell")  # fmt: skip
    ref = f"the documented study: {b['seeds']} seeds × {b['steps']:,} steps × {b['episodes']} episodes"
    if steps < 10_000 or episodes < 8:
        what = f"a smoke run: a check of the pipeline, far too small for a finding ({ref})"
    elif seeds < 2:
        what = f"a one-seed run: its cells have no interval across training seeds, so no difference between conditions is resolved ({ref})"
    elif seeds >= b["seeds"] and steps >= b["steps"] and episodes >= b["episodes"]:
        what = f"a study at the documented study's budget ({b['seeds']} seeds × {b['steps']:,} steps × {b['episodes']} episodes)"
    else:
        short = [f"{name} {have:,} < {want:,}" for name, have, want in (("seeds", seeds, b["seeds"]), ("steps", steps, b["steps"]),
                 ("episodes", episodes, b["episodes"])) if have < want]  # fmt: skip
        what = f"a study below the documented budget ({', '.join(short)}; {ref})"
    return f"{head} — {what}."
POLICIES = ("auto", "MultiInputPolicy", "MlpPolicy", "CnnPolicy")


@dataclass(frozen=True)
class RLConfig:
    """The benchmark's task, agent and budget. ``env_kwargs`` go to ``gym.make`` beside ``fog`` and
    ``episode_seconds``; ``policy="auto"`` picks the SB3 policy from the observation space
    (:func:`~fog_gym.experiments.rl_bench.data.policy_for`); ``vec_env`` names a factory of
    :data:`~fog_gym.experiments.rl_bench.data.VEC_ENVS`."""

    env_id: str = "FogDriveRL-v0"
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    conditions: tuple[str, ...] = DEFAULT_CONDITIONS
    algo: str = "PPO"
    policy: str = "auto"
    vec_env: str = "subproc"
    steps: int = 2048
    episodes: int = 8
    envs: int = os.cpu_count() or 1
    episode_seconds: float = 20.0
    checkpoint: int = 10_000
    device: str = "auto"
    torch_threads: int | None = None
    #: sensor sets of the perceived-objects observation (:data:`~.data.SENSOR_SETS`): one agent per set, condition
    #: and seed, and the scripted detection driver per set and test fog (empty: the env's own observation)
    sensor_sets: tuple[str, ...] = ()
    #: keyword arguments of the learner replacing the study's defaults (``--algo-kwarg``)
    algo_kwargs: Mapping[str, Any] = field(default_factory=dict)
    #: the mean training-episode length the curricula are spread over (None: the task's, ``data.EPISODE_STEPS``)
    episode_steps: int | None = None

    def __post_init__(self) -> None:
        import gymnasium as gym

        import fog_gym  # noqa: F401  (registers the ids)

        if self.env_id not in gym.registry:
            raise ValueError(f"env must be a registered Gymnasium id (fog-gym's RL presets: FogDriveRL-v0, "
                             f"FogDriveRLHazard-v0), got {self.env_id!r}")  # fmt: skip
        reserved = sorted({"fog", "episode_seconds"} & set(self.env_kwargs))
        if reserved:
            raise ValueError(f"env_kwargs must not set {reserved}: the condition sets fog, --episode-seconds the length")
        try:
            json.dumps(dict(self.env_kwargs))
        except TypeError as e:
            raise ValueError(f"env_kwargs must be JSON values (they are part of the study's settings): {e}") from None
        object.__setattr__(self, "env_kwargs", dict(self.env_kwargs))
        object.__setattr__(self, "conditions", tuple(self.conditions))
        bad = [c for c in self.conditions if c not in CONDITIONS]
        if bad or not self.conditions or len(set(self.conditions)) < len(self.conditions):
            raise ValueError(f"conditions must be distinct names of {CONDITIONS}, got {list(self.conditions)}")
        if self.algo not in ALGOS:
            raise ValueError(f"algo must be one of {ALGOS}, got {self.algo!r}")
        if self.policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {self.policy!r}")
        if self.vec_env not in VEC_ENVS:
            raise ValueError(f"vec_env must be one of {sorted(VEC_ENVS)}, got {self.vec_env!r}")
        for name, low in (("steps", 64), ("episodes", 1), ("envs", 1), ("checkpoint", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise ValueError(f"{name} must be an integer >= {low}, got {v!r}")
        if not 0 < self.episode_seconds < 1e4:
            raise ValueError(f"episode_seconds must be > 0, got {self.episode_seconds}")
        if self.torch_threads is not None and self.torch_threads < 1:
            raise ValueError(f"torch_threads must be >= 1, got {self.torch_threads}")
        object.__setattr__(self, "sensor_sets", tuple(self.sensor_sets))
        bad = [s for s in self.sensor_sets if s not in SENSOR_SETS]
        if bad or len(set(self.sensor_sets)) < len(self.sensor_sets):
            raise ValueError(f"sensor_sets must be distinct names of {tuple(SENSOR_SETS)}, got {list(self.sensor_sets)}")
        if self.sensor_sets and self.env_kwargs.get("observation") != "objects":
            raise ValueError("sensor_sets need the perceived-objects observation: --observation objects")
        if "sensors" in self.env_kwargs and self.sensor_sets:
            raise ValueError("env_kwargs must not set sensors when sensor_sets does")
        try:
            json.dumps(dict(self.algo_kwargs))
        except TypeError as e:
            raise ValueError(f"algo_kwargs must be JSON values (they are part of the study's settings): {e}") from None
        object.__setattr__(self, "algo_kwargs", dict(self.algo_kwargs))
        if self.episode_steps is not None and (isinstance(self.episode_steps, bool) or not isinstance(self.episode_steps, int)
                                               or self.episode_steps < 1):  # fmt: skip
            raise ValueError(f"episode_steps must be a positive integer, got {self.episode_steps!r}")

    def make_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``gym.make`` besides ``fog``."""
        return {"episode_seconds": self.episode_seconds, **self.env_kwargs}


class RLStudy(Study):
    """Train an agent per condition and seed, evaluate each on every test fog, report the train × test matrix.

    >>> study = RLStudy(RLConfig(conditions=("clear", "moderate"), steps=64, episodes=2, envs=1))
    >>> [u.key for u in study.units([0, 1]) if u.stage == "train"]
    ['clear_s0', 'moderate_s0', 'clear_s1', 'moderate_s1']
    >>> len([u for u in study.units([0]) if u.stage == "eval"]), study.settings()["env"]
    (8, 'FogDriveRL-v0')
    """

    name = "rl-bench"
    command = "fog-gym rl-bench"
    default_out = Path("out/rl_bench")
    own_wall_times = True
    smoke_help = ("a ≈ 2-minute check of the whole pipeline (2 conditions × 256 steps, 2 evaluation episodes, 2-s "
                  "episodes); the default budget is itself a ≈ 20-minute check, far too small for a finding")  # fmt: skip
    description = (
        "The fog RL benchmark: train an agent (PPO or DQN) per fog condition and training seed, evaluate every agent "
        "on clear / light / moderate / dense fog in parallel vector envs, and report a train × test matrix with 95 % "
        "CIs across training seeds.\n\n"
        "Conditions: clear, light, moderate, dense (fixed fog), mixed (a seeded level per episode), curriculum "
        "(clear → 160 → 100 → 50 m in steps), success (advance when 80 % of the last 10 episodes were crash-free) and "
        "continuous (visibility sliding from clear to 50 m linearly in α); the default runs all but moderate.\n\n"
        "Outputs under --out: matrix.md, matrix.json (per cell: mean over training seeds, 95 % Student-t CI across "
        "seeds, episode-level SD; collision rate, return, mean speed, distance driven), heatmap.png, fog_effect.png, "
        "curves.png, curves/<condition>.png, eval/<agent>_<fog>_<episodes>.json, TensorBoard logs in tb/, models in "
        "models/. Run the same command again to continue where it stopped.\n\n"
        "The default budget (7 conditions × 1 seed × 2 048 steps, 8 episodes per cell) finishes in about 20 minutes "
        "on a 2-core CPU: a check of the pipeline, far too small for a finding. The documented study (docs/experiments/"
        "rl_benchmark.md): --seeds 5 --steps 250000 --episodes 32. Every report's budget line says what its run is.")

    def __init__(self, config: RLConfig = RLConfig()) -> None:
        self.config = config
        self.threads = config.torch_threads or (1 if config.envs > 1 else _torch_threads())

    def settings(self) -> dict[str, Any]:
        c = self.config
        out = {"env": c.env_id, "env_kwargs": dict(c.env_kwargs), "algo": c.algo, "policy": c.policy,
               "vec_env": c.vec_env, "steps": c.steps, "episode_seconds": c.episode_seconds, "envs": c.envs}  # fmt: skip
        if c.sensor_sets or c.algo_kwargs:  # studies without them keep the settings (and folders) they had
            out.update(sensor_sets=list(c.sensor_sets), algo_kwargs=dict(c.algo_kwargs))
        if c.episode_steps is not None:
            out["episode_steps"] = c.episode_steps
        return out

    def budget_note(self, seeds: Sequence[int]) -> str:
        c = self.config
        agents = len(seeds) * len(c.conditions) * max(1, len(c.sensor_sets))
        return budget_line(len(seeds), c.steps, c.episodes, agents)

    def announce(self, seeds: Sequence[int]) -> str:
        return f"{self.config.env_id}. {self.budget_note(seeds)}"

    def units(self, seeds: Sequence[int]) -> list[Unit]:
        c = self.config
        sets = c.sensor_sets or (None,)
        agents = [(ss, cond, s) for s in seeds for ss in sets for cond in c.conditions]
        def params(ss: str | None, **kw: Any) -> dict[str, Any]:
            return {**kw, "sensors": ss} if ss else kw  # studies without sensor sets keep the records they had

        train = [Unit("train", agent_name(cond, s, ss), s, params(ss, condition=cond), cpus=c.envs)
                 for ss, cond, s in agents]  # fmt: skip
        evals = [Unit("eval", f"{agent_name(cond, s, ss)}_{t}_{c.episodes}", s, params(ss, condition=cond, test=t),
                      cpus=min(c.envs, c.episodes)) for ss, cond, s in agents for t in TEST_LEVELS]  # fmt: skip
        drivers = [Unit("driver", f"driver_{ss}_{t}_{c.episodes}", 0, {"sensors": ss, "test": t}, cpus=1)
                   for ss in c.sensor_sets for t in TEST_LEVELS]  # fmt: skip
        return drivers + train + evals

    def artefacts(self, unit: Unit) -> list[str]:
        return [f"models/{unit.key}.zip"] if unit.stage == "train" else []

    def run_unit(self, unit: Unit, out: Path, progress: bool) -> dict[str, Any]:
        import torch

        if self.config.device == "cpu" or not torch.cuda.is_available():
            torch.set_num_threads(self.threads)  # the env workers need the cores; more threads only spin against them
        sensors = unit.params.get("sensors")
        if unit.stage == "driver":
            from fog_gym.perception.driver import drive, sensor_reach

            # the driver reads the "list" layout; the layout changes the observation only, never the detections
            kw = {k: v for k, v in self.config.make_kwargs().items() if k not in ("observation", "layout")}
            sset, test, c = tuple(SENSOR_SETS[sensors]), unit.params["test"], self.config
            reach = sensor_reach(sset, test, env_id=c.env_id, **kw)
            return drive(sset, test, reach, c.episodes, EVAL_SEED, env_id=c.env_id, **kw)
        if unit.stage == "train":
            from fog_gym.experiments.rl_bench.train import train_agent

            return train_agent(self.config, unit.params["condition"], unit.seed, out, progress, sensors)
        from fog_gym.experiments.rl_bench.evaluate import evaluate

        agent = agent_name(unit.params["condition"], unit.seed, sensors)
        return evaluate(self.config, out / "models" / f"{agent}.zip", unit.params["test"], sensors=sensors)

    def describe(self, unit: Unit, result: dict[str, Any]) -> str:
        if unit.stage == "driver":
            return f"driver return {result['return']:.1f}, collisions {result['collisions']:.0%}"
        if unit.stage == "train":
            rate = result.get("steps_per_s")
            return f"{result['steps']} steps" + (f" ({rate:.0f} steps/s)" if rate else "")
        return f"collision rate {sum(result['collision']) / len(result['collision']):.0%}"

    def report(self, records: dict[str, dict[str, Any]], out: Path, seeds: Sequence[int]) -> Report:
        from fog_gym.experiments.rl_bench import report as rep
        from fog_gym.experiments.rl_bench.evaluate import METRICS

        c = self.config
        results: dict[Any, Any] = {}
        drivers: dict[str, dict[str, Any]] = {}
        eval_s: dict[str, float] = {}
        for r in records.values():
            params = r["params"]
            if r["stage"] == "driver":
                drivers.setdefault(params["sensors"], {})[params["test"]] = r["result"]
            elif r["stage"] == "eval":
                cond, sset = params["condition"], params.get("sensors")
                results.setdefault(sset, {}).setdefault(cond, {}).setdefault(params["test"], {})[r["seed"]] = r["result"]
                agent = agent_name(cond, r["seed"], sset)
                eval_s[agent] = eval_s.get(agent, 0.0) + r["wall_s"]
        metrics = [m for m, *_ in METRICS]
        tables = {sset: aggregate(res, metrics) for sset, res in results.items()}
        meta = {"env": c.env_id, "env_kwargs": dict(c.env_kwargs), "algo": c.algo, "seeds": len(seeds),
                "steps": c.steps, "episodes": c.episodes, "envs": c.envs, "conditions": list(c.conditions),
                "sensor_sets": list(c.sensor_sets), "algo_kwargs": dict(c.algo_kwargs), "episode_steps": c.episode_steps,
                "budget": self.budget_note(seeds)}  # fmt: skip
        sets = list(c.sensor_sets) or [None]
        agents = [agent_name(cond, s, ss) for ss in sets for cond in c.conditions for s in seeds]
        times = rep.wall_times(out, agents, eval_s)
        figures: dict[str, Any] = {}
        if not c.sensor_sets:
            table = tables.get(None, {})
            text = rep.render_matrix(table, meta) + "\n\n" + "\n".join(rep.render_wall_times(times))
            figures.update({"heatmap.png": lambda p: rep.heatmap(table, p),
                            "fog_effect.png": lambda p: rep.fog_effect(table, c.env_id, p),
                            "curves.png": lambda p: rep.learning_curves(out, c.conditions, seeds, c.env_id, p)})  # fmt: skip
            for cond in c.conditions:
                if any(rep.episode_curve(out, cond, s) is not None for s in seeds):
                    figures[f"curves/{cond}.png"] = lambda p, cond=cond: rep.condition_curves(out, cond, seeds, c.env_id, p)
            data = {"meta": meta, "table": table, "wall_times": times}
            return Report(text, data, "matrix.md", "matrix.json", figures)
        text = rep.render_sensor_study(tables, drivers, meta) + "\n\n" + "\n".join(rep.render_wall_times(times))
        for ss in c.sensor_sets:
            table = rep.complete(tables.get(ss, {}))
            conds = [f"{ss}_{cond}" for cond in c.conditions]
            if table:
                figures[f"heatmap_{ss}.png"] = lambda p, table=table: rep.heatmap(table, p)
                figures[f"fog_effect_{ss}.png"] = lambda p, table=table, ss=ss: rep.fog_effect(table, f"{c.env_id}, {ss}", p)
            figures[f"curves_{ss}.png"] = lambda p, conds=conds, ss=ss: rep.learning_curves(out, conds, seeds,
                                                                                          f"{c.env_id}, {ss}", p)  # fmt: skip
        figures["fog_effect.png"] = lambda p: rep.sensor_fog_effect(tables, drivers, c.env_id, p)
        data = {"meta": meta, "tables": tables, "drivers": drivers, "wall_times": times,
                "result": rep.result_json(tables, drivers, meta)}  # fmt: skip
        return Report(text, data, "matrix.md", "matrix.json", figures)

    @classmethod
    def add_arguments(cls, p: argparse.ArgumentParser) -> None:
        from fog_gym.envs.presets import OBSERVATIONS
        from fog_gym.perception.objects import LAYOUTS

        d = RLConfig()
        p.add_argument("--env", default=d.env_id,
                       help="the task, a registered id: FogDriveRL-v0 (default) or FogDriveRLHazard-v0 (stalled vehicles ahead)")
        p.add_argument("--env-kwarg", action="append", default=[], metavar="KEY=VALUE", type=_kwarg,
                       help="extra keyword argument of gym.make (repeatable; VALUE is read as JSON, else as text)")
        p.add_argument("--observation", choices=OBSERVATIONS, default=None,
                       help="the RL preset's observation (default pixels: front camera + LiDAR bird's-eye image; "
                            "objects: the perceived objects); short for --env-kwarg observation=...")
        p.add_argument("--layout", choices=LAYOUTS, default=None,
                       help="layout of the perceived objects (default list); short for --env-kwarg layout=...")
        p.add_argument("--conditions", nargs="+", choices=CONDITIONS, default=list(DEFAULT_CONDITIONS),
                       help="training conditions (default: all but moderate)")
        p.add_argument("--algo", choices=ALGOS, default=d.algo, help="the learner (default PPO)")
        p.add_argument("--policy", choices=POLICIES, default=d.policy,
                       help="SB3 policy (default auto: MultiInputPolicy for Dict observations, MlpPolicy for Box)")
        p.add_argument("--vec-env", choices=sorted(VEC_ENVS), default=d.vec_env,
                       help="vector-env factory (default subproc: SB3's SubprocVecEnv)")
        p.add_argument("--steps", type=int, default=None,
                       help="training steps per agent (default 2048; the documented study: 250000)")
        p.add_argument("--episodes", type=int, default=None,
                       help="evaluation episodes per agent and test fog (default 8; a study: >= 32)")
        p.add_argument("--envs", type=int, default=d.envs, help="envs in parallel per agent (default: the CPU count)")
        p.add_argument("--device", default=d.device, help="torch device: auto (GPU when present), cpu or cuda")
        p.add_argument("--torch-threads", type=int, default=None,
                       help="torch threads on the CPU (default: 1 with subprocess envs, else torch's own)")
        p.add_argument("--checkpoint", type=int, default=d.checkpoint, help="checkpoint every N steps (default 10000)")
        p.add_argument("--episode-seconds", type=float, default=None,
                       help="episode length in seconds (default 20, FogDriveRL-v0's; shorter only for smoke runs)")
        p.add_argument("--sensor-sets", nargs="+", choices=sorted(SENSOR_SETS), default=[],
                       help="one agent per sensor set of the perceived-objects observation (needs --observation "
                            "objects), and the scripted detection driver per set and test fog")
        p.add_argument("--episode-steps", type=int, default=None, metavar="N",
                       help="mean training-episode length the curricula are spread over (default: the task's "
                            "measured one; the step curriculum reaches dense fog after 60 %% of steps / N episodes)")
        p.add_argument("--algo-kwarg", action="append", default=[], metavar="KEY=VALUE", type=_kwarg,
                       help="learner argument replacing the study's default (repeatable; VALUE read as JSON), "
                            "e.g. n_steps=128 batch_size=512 n_epochs=5")

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> RLStudy:
        conditions, steps, episodes, seconds = args.conditions, args.steps, args.episodes, args.episode_seconds
        if args.smoke:
            conditions = ["clear", "curriculum"] if args.conditions == list(DEFAULT_CONDITIONS) else conditions
            steps, episodes, seconds = steps or 256, episodes or 2, seconds or 2.0
        env_kwargs = dict(args.env_kwarg)
        for key in ("observation", "layout"):
            value = getattr(args, key, None)
            if value is not None and env_kwargs.setdefault(key, value) != value:
                raise ValueError(f"--{key} {value} contradicts --env-kwarg {key}={env_kwargs[key]}")
        config = RLConfig(env_id=args.env, env_kwargs=env_kwargs, conditions=tuple(conditions),
                          algo=args.algo, policy=args.policy, vec_env=args.vec_env, steps=steps or 2048,
                          episodes=episodes or 8, envs=args.envs, episode_seconds=seconds or 20.0,
                          checkpoint=args.checkpoint, device=args.device, torch_threads=args.torch_threads,
                          sensor_sets=tuple(args.sensor_sets), algo_kwargs=dict(args.algo_kwarg),
                          episode_steps=args.episode_steps)  # fmt: skip
        return cls(config)


def _kwarg(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` with VALUE as JSON (numbers, lists, quoted text, true/false/null), else as plain text.

    >>> _kwarg('sensors=["lidar"]'), _kwarg("observation=objects"), _kwarg("bev_size=32")
    (('sensors', ['lidar']), ('observation', 'objects'), ('bev_size', 32))
    """
    key, sep, value = text.partition("=")
    if not sep or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE with KEY a Python name, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def _torch_threads() -> int:
    import torch

    return torch.get_num_threads()

