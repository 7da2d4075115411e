"""The fog-bank study: its curriculum, its per-episode measures, its settings, and (slow) the whole pipeline."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fog_gym.experiments.bank_study import CONDITIONS, DRIVER_SETS, BankStudy, curriculum_banks, episode_measures


def test_the_curriculum_thickens_the_banks_monotonically_in_extinction_and_then_holds_the_tests_range():
    ps = np.linspace(0.0, 1.0, 21)
    lows = [1.0 / curriculum_banks(p).visibility[0] for p in ps]
    highs = [1.0 / curriculum_banks(p).visibility[1] for p in ps]
    assert np.all(np.diff(lows) >= 0) and np.all(np.diff(highs) >= 0)
    assert curriculum_banks(0.6) == curriculum_banks(1.0) and curriculum_banks(1.0).visibility == (25.0, 80.0)
    mid = curriculum_banks(0.3).visibility[0]  # halfway in extinction between 160 and 25 m
    assert 1.0 / mid == pytest.approx(0.5 / 160.0 + 0.5 / 25.0)


def test_episode_measures_read_the_speed_before_and_at_the_face_and_place_the_crash():
    u = np.arange(0.0, 400.0, 5.0)  # 5 m per frame, the face at 200 m, 100 m deep
    v = np.where(u < 150.0, 30.0, 12.0)
    m = episode_measures(v, u, 200.0, 100.0, crashed=True, total=10.0)
    assert (m["v_before"], m["v_entry"], m["slowed"], m["collision"]) == (30.0, 12.0, True, True)
    assert m["crash_in_bank"] is False  # it ended at u = 395 m, past the bank
    short = episode_measures(v[:30], u[:30], 200.0, 100.0, crashed=True, total=1.0)  # ended at 145 m, before it
    assert short["v_entry"] is None and short["slowed"] is None and short["crash_in_bank"] is False
    inside = episode_measures(v[:50], u[:50], 200.0, 100.0, crashed=True, total=1.0)  # ended at 245 m
    assert inside["crash_in_bank"] is True
    assert m["profile"][0] == 30.0 and m["profile"][-1] == 12.0  # −200 m and +100 m from the face


@pytest.mark.parametrize("kwargs, match", [({"steps": 10}, "steps"), ({"envs": 0}, "envs"), ({"episodes": 1.5}, "episodes"),
                                           ({"conditions": ("fog",)}, "conditions"),
                                           ({"conditions": ("banks", "banks")}, "conditions"),
                                           ({"checkpoint": 0}, "checkpoint")])  # fmt: skip
def test_bad_settings_are_refused_naming_them(kwargs, match):
    with pytest.raises(ValueError, match=match):
        BankStudy(**kwargs)


def test_the_units_train_then_test_every_condition_per_seed_and_drive_the_scripted_bounds():
    units = BankStudy().units([0, 1])
    stages = [u.stage for u in units]
    assert stages == sorted(stages, key=["train", "eval", "driver"].index)
    assert {u.key for u in units if u.stage == "train"} == {f"{c}_s{s}" for c in CONDITIONS for s in (0, 1)}
    drivers = [u.key for u in units if u.stage == "driver"]
    assert drivers[:2] == ["clear", "fog"] and len(drivers) == 2 * len(DRIVER_SETS)


@pytest.mark.slow
def test_the_smoke_study_runs_end_to_end_and_reports(tmp_path):
    from fog_gym.experiments.bank_study import main

    assert main(["--smoke", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "bank_study.json").read_text())
    assert set(data["stats"]) == set(CONDITIONS)
    assert set(data["drivers"]) == {f"{n}/{r}" for n in DRIVER_SETS for r in ("clear", "fog")}
    cl = data["drivers"]
    assert cl["camera+lidar/clear"]["reach_m"] > cl["camera+lidar/fog"]["reach_m"]  # fog shortens the reach
    assert cl["radar/clear"]["reach_m"] == pytest.approx(cl["radar/fog"]["reach_m"], rel=0.05)  # but not the radar's
    assert (tmp_path / "bank_study.png").stat().st_size > 10_000


def test_a_training_unit_cut_short_continues_from_its_last_checkpoint(tmp_path):
    from fog_gym.experiments.runner import Unit

    unit = Unit("train", "banks_s0", 0, {"condition": "banks"})
    first = BankStudy(steps=512, envs=2, episodes=1, checkpoint=256)._train(unit, tmp_path, progress=False)
    assert first["trained"] == 512 and (tmp_path / "checkpoints" / "banks_s0" / "model.zip").exists()
    # the same unit asked for more steps (as if the first run had stopped at its checkpoint) trains only the rest
    more = BankStudy(steps=1024, envs=2, episodes=1, checkpoint=256)._train(unit, tmp_path, progress=False)
    assert more["trained"] == 512 and (tmp_path / "models" / "banks_s0.zip").exists()
