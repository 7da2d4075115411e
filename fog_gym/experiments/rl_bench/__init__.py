"""The fog RL benchmark: does training in fog (fixed, mixed, or a curriculum) make a driving agent robust to it?

Shaped like the other studies: :mod:`~.data` (conditions, schedules, envs, the vector-env factory),
:mod:`~.train` (one agent), :mod:`~.evaluate` (one agent at one test fog), :mod:`~.report` (matrices, statements,
figures), :mod:`~.study` (the study the runner drives, and its command line: ``fog-gym rl-bench``, ``python -m
fog_gym.experiments.rl_bench``). Beside it, two diagnostics of the hazard task: :mod:`~.hazard_check` (what
seeing is worth to scripted drivers, how far the observation sees) and :mod:`~.probe` (what trained agents do).
Needs the ``rl`` extra.

Example (sketch: minutes of CPU):
    >>> # from fog_gym.experiments.runner import run
    >>> # run(RLStudy(RLConfig(conditions=("clear", "curriculum"), steps=4096)), "out/rl", seeds=2)
"""

from fog_gym.experiments.rl_bench.study import RLConfig, RLStudy

__all__ = ["RLConfig", "RLStudy"]
