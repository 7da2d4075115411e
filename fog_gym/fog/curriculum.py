"""The one curriculum driver: which fog the next episode gets, from a :class:`~fog_gym.fog.schedules.FogSchedule`.

A :class:`Curriculum` counts episodes in the order they start and finish, asks the schedule for the level of each
episode as it starts (:meth:`Curriculum.next_level`) and tells it how each finished one went
(:meth:`Curriculum.finish`: success = no crash). Every way of running a curriculum is a thin adapter over it that
applies the level at the very next episode of the env that needs one:

* one env: :class:`fog_gym.wrappers.FogCurriculum` (a Gymnasium wrapper: the level before each ``reset``);
* a Gymnasium vector env (``gym.make_vec``, fog-gym's native vector env included):
  :class:`fog_gym.wrappers.VectorFogCurriculum` (the level of a finished sub-env before its next-step reset);
* an SB3 vector env: :class:`fog_gym.rl.sb3.VecFogCurriculum` (SB3 resets inside ``step``, so it re-resets that
  sub-env in the new fog).

Its state (the schedule with its history and both counters) pickles, so an interrupted training run resumes it.

Example:
    >>> from fog_gym.fog.schedules import StepSchedule
    >>> c = Curriculum(StepSchedule(episodes_per_level=1))
    >>> [c.next_level() for _ in range(3)], c.started
    (['clear', 160.0, 100.0], 3)
    >>> c.finish(success=True); c.finished
    1
"""

from __future__ import annotations

from typing import Any

from fog_gym.fog.physics import parse_fog
from fog_gym.fog.schedules import FogSchedule


class Curriculum:
    """Drive ``schedule`` over the episodes of one env or of all sub-envs of a vector env together."""

    def __init__(self, schedule: FogSchedule) -> None:
        if not isinstance(schedule, FogSchedule):
            raise ValueError(f"schedule must be a FogSchedule, got {type(schedule).__name__}")
        self.schedule = schedule
        self.started = 0  # episodes given a level so far
        self.finished = 0  # episodes reported by finish()

    def next_level(self) -> Any:
        """The level of the episode about to start (the schedule's level for this episode's index)."""
        level = self.schedule.level(self.started)
        parse_fog(level)  # a schedule's level must be a valid fog
        self.started += 1
        return level

    def finish(self, success: bool) -> None:
        """Report how an episode ended (success: no crash)."""
        self.finished += 1
        self.schedule.record(bool(success))

    def __repr__(self) -> str:
        return f"Curriculum({type(self.schedule).__name__}, started={self.started}, finished={self.finished})"
