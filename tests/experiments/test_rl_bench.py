"""The RL benchmark (fog_gym.experiments.rl_bench) through the study runner: a smoke run that resumes and reports
CIs across seeds, its statistics and statements, its parameters (task, env kwargs, conditions, algorithm, vector-env
factory, policy), Ray, and the hazard task's two diagnostics (scripted drivers, agent probe)."""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fog_gym.experiments import runner
from fog_gym.experiments.rl_bench import RLConfig, RLStudy, hazard_check, probe
from fog_gym.experiments.rl_bench import data as rl_data
from fog_gym.experiments.rl_bench import report as rl_report

TINY = ["--steps", "64", "--episodes", "2", "--envs", "1", "--episode-seconds", "0.6", "--checkpoint", "32",
        "--device", "cpu"]  # fmt: skip


def test_rl_benchmark_smoke_resumes_and_reports_cis_across_seeds(tmp_path):
    pytest.importorskip("stable_baselines3")
    argv = ["--conditions", "clear", "curriculum", "--seeds", "2", *TINY, "--out", str(tmp_path)]
    assert runner.main(RLStudy, argv) == 0
    data = json.loads((tmp_path / "matrix.json").read_text())
    cell = data["table"]["curriculum"]["dense"]["collision"]
    assert cell["seeds"] == 2 and cell["episodes"] == 4 and cell["ci95"] is not None
    assert {"clear", "light", "moderate", "dense"} == set(data["table"]["clear"])
    text = (tmp_path / "matrix.md").read_text()
    assert "distance driven [m]" in text and "Fog effect" in text and "Against the clear-trained agents" in text
    assert "— a smoke run: a check of the pipeline" in text and "4 agents (2 training seeds)" in text  # its own numbers
    # wall times: every agent's training steps come from its monitor logs (finished episodes: at most the budget
    # plus the steps of one episode per env), every evaluation cell recorded its time
    times = data["wall_times"]
    assert set(times) == {"clear_s0", "clear_s1", "curriculum_s0", "curriculum_s1"}
    assert all(0 < t["steps"] <= 64 + 3 and t["train_s"] > 0 and t["eval_s"] > 0 for t in times.values())
    assert "## Wall time" in text and "| curriculum_s1 |" in text and "Units in all:" in text
    assert all((tmp_path / f).exists() for f in ("heatmap.png", "fog_effect.png", "curves.png"))
    assert sorted(p.name for p in (tmp_path / "curves").iterdir()) == ["clear.png", "curriculum.png"]
    assert not list(tmp_path.rglob(".*tmp*"))  # every report file was written through a temporary one
    # killed after a checkpoint: the model is gone, the checkpoint stays -> training continues from it
    (tmp_path / "models" / "curriculum_s1.zip").unlink()
    evals = sorted((tmp_path / "eval").glob("*.json"))
    kept = json.loads((tmp_path / "eval" / "clear_s0_dense_2.json").read_text())
    (tmp_path / "eval" / "curriculum_s1_dense_2.json").unlink()
    from stable_baselines3 import PPO

    assert PPO.load(tmp_path / "checkpoints" / "curriculum_s1" / "model.zip").num_timesteps >= 32
    assert runner.main(RLStudy, argv) == 0
    assert PPO.load(tmp_path / "models" / "curriculum_s1.zip").num_timesteps >= 64
    assert sorted((tmp_path / "eval").glob("*.json")) == evals
    assert json.loads((tmp_path / "eval" / "clear_s0_dense_2.json").read_text()) == kept  # a finished cell is kept
    # the resumed agent's wall time and steps add up over both monitor parts (the second may hold no episode)
    resumed = json.loads((tmp_path / "matrix.json").read_text())["wall_times"]["curriculum_s1"]
    assert len(list((tmp_path / "monitor").glob("curriculum_s1_*.monitor.csv"))) == 2
    assert resumed["train_s"] >= times["curriculum_s1"]["train_s"] and resumed["steps"] >= times["curriculum_s1"]["steps"]


def test_rl_benchmark_ci_is_student_t_across_seeds():
    assert round(runner.ci95_across([1.0, 2.0, 3.0]), 3) == 2.484  # t(0.975, 2) · 1 / √3
    assert runner.ci95_across([5.0]) is None
    table = runner.aggregate({"clear": {"dense": {0: {"collision": [0, 1], "return": [1, 3], "speed": [20, 22],
                                                       "distance": [100, 120]}}}}, ["collision", "return"])  # fmt: skip
    assert table["clear"]["dense"]["return"] == {"mean": 2.0, "ci95": None, "seeds": 1,
                                                 "episode_std": pytest.approx(1.4142, 1e-4), "episodes": 2}  # fmt: skip
    assert set(table["clear"]["dense"]) == {"collision", "return"}


def test_rl_benchmark_significance_compares_ci_intervals():
    def cell(m, ci):
        return {"collision": {"mean": m, "ci95": ci}, "return": {"mean": 50 * (1 - m), "ci95": ci and 50 * ci}}

    table = {"clear": {"clear": cell(0.2, 0.05), "dense": cell(0.3, 0.1)},
             "dense": {"clear": cell(0.5, 0.1), "dense": cell(0.35, 0.1)},
             "light": {"clear": cell(0.2, None), "dense": cell(0.2, None)}}  # fmt: skip
    lines = rl_report.significance(table)
    assert "- clear: collision rate 20% clear vs 30% dense — CIs overlap; return 40.0 vs 35.0 — CIs overlap" in lines
    assert any(line.startswith("- tested clear: dense collision rate 50% vs clear 20% — separated") for line in lines)
    assert any(line.startswith("- tested dense: dense collision rate 35% vs clear 30% — CIs overlap") for line in lines)
    assert any(line.startswith("- light:") and "not testable (one seed)" in line for line in lines)


def test_matrix_rows_follow_condition_order_and_one_seed_has_no_ci():
    one = {m: {"mean": 0.5, "ci95": None, "seeds": 1, "episode_std": 0.1, "episodes": 2}
           for m in ("collision", "return", "speed", "distance")}  # fmt: skip
    table = {c: {t: one for t in rl_data.TEST_LEVELS} for c in ("mixed", "moderate", "clear", "continuous")}
    text = rl_report.render_matrix(table, {"env": "FogDriveRL-v0", "seeds": 1, "steps": 64, "episodes": 2})
    rows = [ln.split("|")[1].strip() for ln in text.split("## return")[1].split("##")[0].splitlines() if ln.startswith("| ")]
    assert rows[1:] == ["clear", "moderate", "mixed", "continuous"]  # the conditions' order, not the table's
    assert "0.5 ± n/a [0.1]" in text


def test_rl_benchmark_refuses_a_study_folder_of_another_task_before_work(tmp_path):
    study = RLStudy(RLConfig(steps=64, episode_seconds=0.6, envs=1))
    runner.write_atomic(tmp_path / "study.json", {"study": "rl-bench", "settings": study.settings(), "data": {}})
    with pytest.raises(SystemExit) as e:
        runner.main(RLStudy, ["--env", "FogDriveRLHazard-v0", *TINY, "--out", str(tmp_path)])
    assert str(e.value.code).startswith(f"fog-gym rl-bench: {tmp_path} holds a rl-bench study with other settings")
    assert '"FogDriveRL-v0" there, "FogDriveRLHazard-v0" here' in str(e.value.code)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["study.json"]  # nothing ran
    with pytest.raises(SystemExit) as e:  # a usage error: argparse's status 2
        runner.main(RLStudy, ["--torch-threads", "0", "--out", str(tmp_path / "b")])
    assert e.value.code == 2 and not (tmp_path / "b").exists()


@pytest.mark.parametrize("kwargs, message", [
    ({"env_id": "FogDrive-v9"}, "registered Gymnasium id"), ({"conditions": ("heavy",)}, "conditions must"),
    ({"conditions": ()}, "conditions must"), ({"algo": "SAC"}, "algo must"), ({"vec_env": "ray"}, "vec_env must"),
    ({"policy": "Transformer"}, "policy must"), ({"steps": 10}, "steps must"), ({"envs": 0}, "envs must"),
    ({"env_kwargs": {"fog": "dense"}}, "must not set"), ({"env_kwargs": {"x": object()}}, "JSON values"),
    ({"episode_seconds": 0.0}, "episode_seconds"),
])  # fmt: skip
def test_bad_settings_are_refused_naming_the_setting(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RLConfig(**kwargs)


def test_rl_benchmark_spreads_the_curricula_over_each_tasks_expected_episodes():
    for env, per_level in (("FogDriveRL-v0", 100), ("FogDriveRLHazard-v0", 333)):
        _, step = rl_data.schedule_for("curriculum", 0, 50_000, env, 20.0)
        _, cont = rl_data.schedule_for("continuous", 0, 50_000, env, 20.0)
        assert step.episodes_per_level == per_level  # dense fog from 60 % of the expected episodes on
        assert cont.episodes == per_level * 4  # the slide ends at 80 %
    assert rl_data.schedule_for("curriculum", 0, 64, "FogDriveRL-v0", 0.6)[1].episodes_per_level == 4  # 3-step episodes
    assert rl_data.schedule_for("moderate", 0, 64, "FogDriveRL-v0", 0.6) == ("moderate", None)


def test_every_unit_is_one_agent_or_one_cell_seed_major():
    study = RLStudy(RLConfig(conditions=("clear", "moderate", "success"), steps=64, episodes=3, envs=2))
    units = study.units([0, 1])
    train = [u for u in units if u.stage == "train"]
    assert [u.key for u in train] == ["clear_s0", "moderate_s0", "success_s0", "clear_s1", "moderate_s1", "success_s1"]
    assert all(u.cpus == 2 for u in train) and study.artefacts(train[0]) == ["models/clear_s0.zip"]
    evals = [u for u in units if u.stage == "eval"]
    assert len(evals) == 6 * 4 and evals[0].key == "clear_s0_clear_3" and evals[0].params == {"condition": "clear", "test": "clear"}


def test_the_policy_fits_the_observation_space_and_env_kwargs_reach_the_env():
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    venv = rl_data.vec_env("subproc", "FogDriveRL-v0", 1, "dense", 0, {"episode_seconds": 0.6, "camera_size": [40, 40],
                                                                       "bev_size": 40})  # fmt: skip
    assert venv.observation_space["CAM_FRONT"].shape == (3, 40, 40) and venv.observation_space["LIDAR_BEV"].shape == (2, 40, 40)
    assert rl_data.policy_for(venv.observation_space) == "MultiInputPolicy"
    venv.close()
    assert rl_data.policy_for(gym.spaces.Box(0, 1, (7, 3))) == "MlpPolicy"
    with pytest.raises(ValueError, match="no policy"):
        rl_data.policy_for(gym.spaces.Discrete(3))
    with pytest.raises(ValueError, match="vec_env must be one of"):
        rl_data.vec_env("gymnasium", "FogDriveRL-v0", 1, "dense", 0, {})


def test_dqn_trains_through_a_swapped_vector_env_factory_and_keeps_its_replay_buffer(tmp_path, monkeypatch):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import DQN

    from fog_gym.experiments.rl_bench.evaluate import evaluate
    from fog_gym.experiments.rl_bench.train import train_agent

    made = []

    def counting(env_id, n, fog, seed, kwargs):
        made.append((env_id, n, fog, seed, dict(kwargs)))
        return rl_data.subproc_vec_env(env_id, n, fog, seed, kwargs)

    monkeypatch.setitem(rl_data.VEC_ENVS, "counting", counting)
    config = RLConfig(env_kwargs={"camera_size": [40, 40], "bev_size": 40}, algo="DQN", vec_env="counting", steps=64,
                      episodes=2, envs=1, episode_seconds=0.6, checkpoint=32, device="cpu")  # fmt: skip
    result = train_agent(config, "moderate", 3, tmp_path, progress=False)
    assert result["steps"] == 64 and result["trained"] == 64
    assert made == [("FogDriveRL-v0", 1, "moderate", 3000, {"episode_seconds": 0.6, "camera_size": [40, 40], "bev_size": 40})]
    model = DQN.load(tmp_path / "models" / "moderate_s3.zip")
    assert model.num_timesteps == 64 and model.observation_space["CAM_FRONT"].shape == (3, 40, 40)
    assert (tmp_path / "checkpoints" / "moderate_s3" / "replay.pkl").stat().st_size > 0
    r = evaluate(config, tmp_path / "models" / "moderate_s3.zip", "dense")
    assert len(made) == 2 and made[1][2:4] == ("dense", rl_data.EVAL_SEED)
    assert len(r["return"]) == 2 and set(r) == {"return", "collision", "speed", "distance"}


def test_ray_without_the_extra_fails_before_any_work(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(SystemExit) as e:
        runner.main(RLStudy, [*TINY, "--ray", "auto", "--out", str(tmp_path / "out")])
    assert str(e.value.code) == "fog-gym rl-bench: --ray needs the optional 'ray' extra: pip install 'fog-gym[ray]'"
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_ray_tasks_give_the_local_runs_results(tmp_path):
    pytest.importorskip("stable_baselines3")
    ray = pytest.importorskip("ray")
    argv = ["--conditions", "clear", "success", *TINY]
    assert runner.main(RLStudy, [*argv, "--out", str(tmp_path / "local")]) == 0
    try:
        assert runner.main(RLStudy, [*argv, "--ray", "local", "--out", str(tmp_path / "ray")]) == 0
    finally:
        ray.shutdown()
    for path in sorted((tmp_path / "local" / "eval").glob("*.json")):
        local, remote = (json.loads((tmp_path / d / "eval" / path.name).read_text()) for d in ("local", "ray"))
        assert remote["result"] == local["result"], path.name
    tables = [json.loads((tmp_path / d / "matrix.json").read_text())["table"] for d in ("local", "ray")]
    assert tables[0] == tables[1]


def test_local_jobs_give_the_one_process_runs_results(tmp_path):
    pytest.importorskip("stable_baselines3")
    # the perceived objects on the native vector env: no env subprocesses, so the test times the runner, not spawns
    argv = ["--conditions", "clear", "success", *TINY, "--env", "FogDriveRLHazard-v0", "--observation", "objects",
            "--vec-env", "native"]  # fmt: skip
    assert runner.main(RLStudy, [*argv, "--out", str(tmp_path / "one")]) == 0
    assert runner.main(RLStudy, [*argv, "--jobs", "2", "--out", str(tmp_path / "two")]) == 0
    for path in sorted((tmp_path / "one" / "eval").glob("*.json")):
        one, two = (json.loads((tmp_path / d / "eval" / path.name).read_text()) for d in ("one", "two"))
        assert two["result"] == one["result"], path.name
    tables = [json.loads((tmp_path / d / "matrix.json").read_text())["table"] for d in ("one", "two")]
    assert tables[0] == tables[1]


# -- the hazard task's diagnostics --------------------------------------------------------------------------------
def test_seeing_further_earns_more_and_a_blind_driver_crashes():
    blind = hazard_check.run_driver("blind", 25.0, 2, 2_000_000)
    near, far = (hazard_check.run_driver("sighted", d, 2, 2_000_000) for d in (15.0, 35.0))
    assert blind["collision"] == 1.0 and far["collision"] == 0.0
    assert far["return"] > near["return"] > 0.0


def test_calibration_refuses_bad_settings_before_work(capsys):
    for argv in (["--episodes", "1"], ["--sights", "80"], ["--speeds", "-5"]):
        with pytest.raises(SystemExit):
            hazard_check.main(argv)
    assert "must" in capsys.readouterr().err


def test_agent_probe_counts_passed_vehicles_and_near_hazards_as_documented():
    # a vehicle 20 m ahead that the ego closes in on at 10 m per step is passed once it is 5 m behind
    steps = np.array([[20.0 - 10.0 * t] for t in range(4)])  # 20, 10, 0, −10
    assert probe.passed(steps) == 1 and probe.passed(steps[:3]) == 0
    hz = np.array([[39.0, -1.9, 4.5, 1.9], [41.0, 0.0, 4.5, 1.9]])
    assert probe.hazard_near(hz, 40.0) and not probe.hazard_near(hz[1:], 40.0)


@given(st.lists(st.floats(-200, 200), min_size=1, max_size=30), st.integers(1, 5))
@settings(max_examples=50, deadline=None)
def test_agent_probe_never_counts_more_passes_than_vehicles(col, k):
    aheads = np.tile(np.array(col)[:, None], (1, k))
    n = probe.passed(aheads)
    assert n in (0, k)  # identical columns: all passed or none
    assert n == (k if any(a > 0 and min(col[i:]) < -5 for i, a in enumerate(col)) else 0)


def test_agent_probe_refuses_bad_settings_before_work(tmp_path, capsys):
    for argv in ([str(tmp_path / "none.zip")], [str(tmp_path / "none.zip"), "--episodes", "0"],
                 [str(tmp_path / "none.zip"), "--near", "-1"]):  # fmt: skip
        with pytest.raises(SystemExit):
            probe.main(argv + ["--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert "no such model file" in err and "must be" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kwargs, message", [
    ({"sensor_sets": ("sonar",)}, "sensor_sets must"), ({"sensor_sets": ("lidar", "lidar")}, "sensor_sets must"),
    ({"sensor_sets": ("lidar",)}, "--observation objects"),
    ({"sensor_sets": ("lidar",), "env_kwargs": {"observation": "objects", "sensors": ["radar"]}}, "must not set sensors"),
    ({"algo_kwargs": {"n_steps": object()}}, "algo_kwargs must be JSON"),
])  # fmt: skip
def test_bad_sensor_study_settings_are_refused_naming_the_setting(kwargs, message):
    with pytest.raises(ValueError, match=message):
        RLConfig(**kwargs)


def test_observation_and_layout_flags_are_the_env_kwargs_they_stand_for():
    from fog_gym.experiments.runner import build_parser

    def parse(argv):
        return RLStudy.from_args(build_parser(RLStudy).parse_args(argv)).config

    short = parse(["--observation", "objects", "--layout", "lanes"])
    long = parse(["--env-kwarg", "observation=objects", "--env-kwarg", "layout=lanes"])
    assert short == long and short.env_kwargs == {"observation": "objects", "layout": "lanes"}
    assert parse(["--observation", "pixels"]).env_kwargs == {"observation": "pixels"}
    with pytest.raises(ValueError, match="--observation pixels contradicts --env-kwarg observation=objects"):
        parse(["--observation", "pixels", "--env-kwarg", "observation=objects"])


def test_a_sensor_study_has_one_driver_per_set_and_fog_then_agents_per_set_condition_and_seed():
    config = RLConfig(env_id="FogDriveRLHazard-v0", env_kwargs={"observation": "objects"}, conditions=("clear", "dense"),
                      sensor_sets=("lidar", "radar"), steps=64, episodes=2, envs=1)  # fmt: skip
    units = RLStudy(config).units([0])
    drivers = [u.key for u in units if u.stage == "driver"]
    assert drivers == [f"driver_{s}_{t}_2" for s in ("lidar", "radar") for t in ("clear", "light", "moderate", "dense")]
    train = [u for u in units if u.stage == "train"]
    assert [u.key for u in train] == ["lidar_clear_s0", "lidar_dense_s0", "radar_clear_s0", "radar_dense_s0"]
    assert train[2].params == {"condition": "clear", "sensors": "radar"}
    # a study without sensor sets keeps the settings (and so the folders) it had before sensor sets existed
    assert "sensor_sets" not in RLStudy(RLConfig(steps=64)).settings()
    assert RLStudy(config).settings()["sensor_sets"] == ["lidar", "radar"]


def test_the_sensor_study_env_sees_only_its_sensor_set_and_the_learner_takes_the_overrides(tmp_path):
    pytest.importorskip("stable_baselines3")
    from fog_gym.experiments.rl_bench.train import new_model

    kwargs = {"observation": "objects", "sensors": rl_data.SENSOR_SETS["radar"]}
    venv = rl_data.vec_env("native", "FogDriveRLHazard-v0", 2, "clear", 0, kwargs)
    obs = venv.reset()
    # features: presence, x, y, vx, vy, lane and one flag per sensor of the set
    assert obs.shape[0] == 2 and obs.shape[-1] == 6 + 1
    model = new_model("PPO", "MlpPolicy", venv, 64, 2, 0, "cpu", str(tmp_path),
                      overrides={"n_steps": 16, "batch_size": 32, "n_epochs": 2})  # fmt: skip
    assert (model.n_steps, model.batch_size, model.n_epochs) == (16, 32, 2)
    venv.close()
