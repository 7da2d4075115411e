"""RL preset, fog schedules and the SB3 vector-env curriculum, and the SB3 path (marked slow); the observation and
curriculum wrappers have their own test files."""

import gymnasium as gym
import numpy as np
import pytest

from fog_gym.fog.schedules import MixedSampler, StepSchedule
from tests.helpers import ROOT, load_module


def test_preset_spaces_match_observations():
    env = gym.make("FogDriveRL-v0", fog="moderate")
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs) and info["fog"]["visibility_m"] == 100.0
    for _ in range(3):
        obs, *_ = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
    assert obs["CAM_FRONT"].shape == (3, 64, 64) and obs["LIDAR_BEV"].shape == (2, 64, 64)
    assert obs["LIDAR_BEV"][0].any()  # the road's edge, guard rails and cars are seen


def test_mixed_sampler_is_seeded_and_covers_every_level():
    a = [MixedSampler(seed=4).level(e) for e in range(200)]
    assert a == [MixedSampler(seed=4).level(e) for e in range(200)]
    assert a != [MixedSampler(seed=5).level(e) for e in range(200)]
    assert set(a) == {"clear", 160.0, 100.0, 50.0}


@pytest.mark.slow
def test_sb3_check_env_and_short_ppo_run(tmp_path):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from fog_gym.rl.sb3 import curriculum_callback

    check_env(gym.make("FogDriveRL-v0"))
    check_env(gym.make("FogDriveRLHazard-v0", fog="dense"))
    # "fog_gym:" makes gym.make import fog_gym in the worker processes (SB3 starts them with forkserver)
    venv = SubprocVecEnv([lambda: gym.make("fog_gym:FogDriveRL-v0", fog="clear", episode_seconds=2.0)] * 2)
    model = PPO("MultiInputPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, seed=0)
    cb = curriculum_callback(StepSchedule(episodes_per_level=1))
    model.learn(total_timesteps=128, callback=cb)
    assert cb.episodes >= 2
    assert venv.env_method("get_wrapper_attr", "fog")[0].name != "clear"  # the schedule reached the sub-envs
    model.save(tmp_path / "ppo.zip")
    assert PPO.load(tmp_path / "ppo.zip").observation_space == model.observation_space
    venv.close()


@pytest.mark.slow
def test_eval_script_writes_the_matrix(tmp_path):
    pytest.importorskip("stable_baselines3")
    import importlib.util
    from pathlib import Path

    root = ROOT / "examples"
    mods = {}
    for name in ("train_curriculum", "eval_matrix"):
        spec = importlib.util.spec_from_file_location(name, root / f"{name}.py")
        mods[name] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mods[name])
    mods["train_curriculum"].main(["--steps", "64", "--conditions", "clear", "dense", "--envs", "1", "--out", str(tmp_path)])
    mods["eval_matrix"].main(["--models", str(tmp_path / "models"), "--episodes", "1", "--out", str(tmp_path)])
    text = (tmp_path / "matrix.md").read_text()
    assert "| clear |" in text and "| dense |" in text and "collision rate" in text
    assert (tmp_path / "matrix.png").read_bytes()[:4] == b"\x89PNG"


def test_eval_matrix_rows_follow_condition_order_and_one_episode_has_no_ci(tmp_path):
    import importlib.util
    from pathlib import Path

    path = ROOT / "examples" / "eval_matrix.py"
    spec = importlib.util.spec_from_file_location("eval_matrix", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    one = {"return": np.array([70.0]), "collision": np.array([0.0]), "speed": np.array([20.0])}
    results = {m.stem: {t: one for t in mod.TEST_LEVELS}
               for m in mod.model_order([Path(f"{c}.zip") for c in ("mixed", "curriculum", "light", "clear", "dense")])}  # fmt: skip
    mod.write_matrix(results, tmp_path, episodes=1)
    rows = [ln.split("|")[1].strip() for ln in (tmp_path / "matrix.md").read_text().splitlines()
            if ln.startswith("| ") and "trained on" not in ln]  # fmt: skip
    assert rows[:5] == ["clear", "light", "dense", "mixed", "curriculum"]
    assert "70.00 ± n/a" in (tmp_path / "matrix.md").read_text() and "± 0.00" not in (tmp_path / "matrix.md").read_text()
    two = mod.ci95(np.array([1.0, 3.0]))
    assert two == (2.0, 1.96)


def _short_rl_env(rank: int):
    def make():
        import gymnasium as gym

        import fog_gym  # noqa: F401

        env = gym.make("FogDriveRL-v0", fog="clear", episode_seconds=0.6, camera_size=(16, 16), bev_size=16)
        env.reset(seed=rank)
        return env

    return make


def test_vec_curriculum_applies_each_level_from_the_very_next_episode_in_subproc_envs():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from fog_gym.fog.schedules import StepSchedule
    from fog_gym.rl.sb3 import VecFogCurriculum

    schedule = StepSchedule(episodes_per_level=1)  # episode k of the run gets level k: clear, 160, 100, 50, 50, …
    venv = VecFogCurriculum(SubprocVecEnv([_short_rl_env(0), _short_rl_env(1)]), schedule)
    venv.reset()
    expected = {i: venv.levels[i] for i in range(2)}
    assert [expected[0], expected[1]] == ["clear", 160.0]
    seen_new_episode = 0
    for _ in range(16):  # 3 policy steps per episode: several episode boundaries per sub-env
        _, _, dones, infos = venv.step(np.zeros(2, np.int64) + 1)
        for i in range(2):
            if dones[i]:
                expected[i] = venv.levels[i]  # the level chosen at this boundary …
                seen_new_episode += 1
                continue
            vis = infos[i]["fog"]["visibility_m"]  # … is the fog of every step of the next episode
            want = float("inf") if expected[i] == "clear" else float(expected[i])
            assert vis == want, (i, vis, want)
            assert infos[i]["fog_level"] == expected[i]
    assert seen_new_episode >= 6 and venv.episodes == seen_new_episode
    venv.close()


def _load_script(name):
    return load_module(f"scripts/{name}.py")


def test_rl_benchmark_smoke_resumes_and_reports_cis_across_seeds(tmp_path):
    pytest.importorskip("stable_baselines3")
    import json

    bench = _load_script("rl_benchmark")
    argv = ["--conditions", "clear", "curriculum", "--seeds", "2", "--steps", "64", "--episodes", "2", "--envs", "1",
            "--episode-seconds", "0.6", "--checkpoint", "32", "--device", "cpu", "--out", str(tmp_path)]  # fmt: skip
    assert bench.main(argv) == 0
    data = json.loads((tmp_path / "matrix.json").read_text())
    cell = data["table"]["curriculum"]["dense"]["collision"]
    assert cell["seeds"] == 2 and cell["episodes"] == 4 and cell["ci95"] is not None
    assert {"clear", "light", "moderate", "dense"} == set(data["table"]["clear"])
    text = (tmp_path / "matrix.md").read_text()
    assert "distance driven [m]" in text and "Fog effect" in text and "Against the clear-trained agents" in text
    # wall times: every agent's training steps come from its monitor logs (finished episodes: at most the budget
    # plus the steps of one episode per env), every evaluation cell recorded its time
    times = data["wall_times"]
    assert set(times) == {"clear_s0", "clear_s1", "curriculum_s0", "curriculum_s1"}
    assert all(0 < t["steps"] <= 64 + 3 and t["train_s"] > 0 and t["eval_s"] > 0 for t in times.values())
    assert "## Wall time" in text and "| curriculum_s1 |" in text
    assert all((tmp_path / f).exists() for f in ("heatmap.png", "fog_effect.png", "curves.png"))
    assert sorted(p.name for p in (tmp_path / "curves").iterdir()) == ["clear.png", "curriculum.png"]
    # killed after a checkpoint: the model is gone, the checkpoint stays -> training continues from it
    (tmp_path / "models" / "curriculum_s1.zip").unlink()
    evals = sorted((tmp_path / "eval").glob("*.json"))
    (tmp_path / "eval" / "curriculum_s1_dense_2.json").unlink()
    from stable_baselines3 import PPO

    assert PPO.load(tmp_path / "checkpoints" / "curriculum_s1" / "model.zip").num_timesteps >= 32
    assert bench.main(argv) == 0
    assert PPO.load(tmp_path / "models" / "curriculum_s1.zip").num_timesteps >= 64
    assert sorted((tmp_path / "eval").glob("*.json")) == evals
    # the resumed agent's wall time and steps add up over both monitor parts (the second may hold no episode)
    resumed = json.loads((tmp_path / "matrix.json").read_text())["wall_times"]["curriculum_s1"]
    assert len(list((tmp_path / "monitor").glob("curriculum_s1_*.monitor.csv"))) == 2
    assert resumed["train_s"] >= times["curriculum_s1"]["train_s"] and resumed["steps"] >= times["curriculum_s1"]["steps"]


def test_rl_benchmark_ci_is_student_t_across_seeds():
    bench = _load_script("rl_benchmark")
    assert round(bench.ci95_across([1.0, 2.0, 3.0]), 3) == 2.484  # t(0.975, 2) · 1 / √3
    assert bench.ci95_across([5.0]) is None
    table = bench.aggregate({"clear": {"dense": {0: {"collision": [0, 1], "return": [1, 3], "speed": [20, 22],
                                                      "distance": [100, 120]}}}})  # fmt: skip
    assert table["clear"]["dense"]["return"] == {"mean": 2.0, "ci95": None, "seeds": 1, "episode_std": pytest.approx(1.4142, 1e-4),
                                                 "episodes": 2}  # fmt: skip


def test_rl_benchmark_significance_compares_ci_intervals():
    bench = _load_script("rl_benchmark")
    def cell(m, ci):
        return {"collision": {"mean": m, "ci95": ci}, "return": {"mean": 50 * (1 - m), "ci95": ci and 50 * ci}}

    table = {"clear": {"clear": cell(0.2, 0.05), "dense": cell(0.3, 0.1)},
             "dense": {"clear": cell(0.5, 0.1), "dense": cell(0.35, 0.1)},
             "light": {"clear": cell(0.2, None), "dense": cell(0.2, None)}}  # fmt: skip
    lines = bench.significance(table)
    assert "- clear: collision rate 20% clear vs 30% dense — CIs overlap; return 40.0 vs 35.0 — CIs overlap" in lines
    assert any(line.startswith("- tested clear: dense collision rate 50% vs clear 20% — separated") for line in lines)
    assert any(line.startswith("- tested dense: dense collision rate 35% vs clear 30% — CIs overlap") for line in lines)
    assert any(line.startswith("- light:") and "not testable (one seed)" in line for line in lines)


def test_rl_benchmark_refuses_a_study_folder_of_another_task_before_work(tmp_path, capsys):
    import json

    bench = _load_script("rl_benchmark")
    (tmp_path / "study.json").write_text(json.dumps({"env": "FogDriveRL-v0", "steps": 64, "episode_seconds": 0.6}))
    with pytest.raises(SystemExit):
        bench.main(["--env", "FogDriveRLHazard-v0", "--steps", "64", "--episode-seconds", "0.6", "--out", str(tmp_path)])
    assert "holds a study of" in capsys.readouterr().err
    assert not (tmp_path / "models").exists()
    with pytest.raises(SystemExit):
        bench.main(["--torch-threads", "0", "--out", str(tmp_path / "b")])


def test_rl_benchmark_spreads_the_curricula_over_each_tasks_expected_episodes(monkeypatch):
    bench = _load_script("rl_benchmark")
    for env, per_level in (("FogDriveRL-v0", 100), ("FogDriveRLHazard-v0", 333)):
        monkeypatch.setitem(bench.ENV_ID, "value", env)
        _, step = bench.schedule_for("curriculum", 0, 50_000)
        _, cont = bench.schedule_for("continuous", 0, 50_000)
        assert step.episodes_per_level == per_level  # dense fog from 60 % of the expected episodes on
        assert cont.episodes == per_level * 4  # the slide ends at 80 %
    monkeypatch.setitem(bench.EPISODE_SECONDS, "value", 0.6)  # smoke runs: 3-step episodes
    assert bench.schedule_for("curriculum", 0, 64)[1].episodes_per_level == 4
