"""The world's narrow surface: nothing outside ``world/traffic_world.py`` and the traffic core reads highway-env, IDM profiles
come from the towns' specs, and one-off label configs never touch the env's config."""

from __future__ import annotations

import ast
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fog_gym.envs.fogdrive import FogDriveEnv
from fog_gym.labels.boxes import LabelConfig
from fog_gym.world.towns import IDM_PROFILES, TOWN_SPECS, TownSpec, apply_idm_profile, highway_env_config
from fog_gym.world.traffic_world import TrafficWorld

ROOT = Path(__file__).resolve().parents[2]
#: The modules allowed to hold highway-env objects: the world and its traffic core.
OWNERS = {"fog_gym/world/traffic_world.py"}


def _files() -> list[Path]:
    paths = [*ROOT.glob("fog_gym/**/*.py"), *ROOT.glob("wrappers/*.py"), *ROOT.glob("scripts/*.py"),
             *ROOT.glob("examples/*.py")]  # fmt: skip
    return [p for p in paths if str(p.relative_to(ROOT)) not in OWNERS and "fog_gym/world/traffic/" not in p.as_posix()]


def test_nothing_outside_the_world_reads_its_highway_env_or_private_members():
    offenders = []
    for path in _files():
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Attribute):
                if node.value.attr == "world" and (node.attr == "hw" or node.attr.startswith("_")):
                    offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} world.{node.attr}")
            if isinstance(node, ast.Attribute) and node.attr == "hw":
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} .hw")
            if isinstance(node, ast.Attribute) and node.attr.startswith("_IDM"):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.attr}")
    assert offenders == []


def test_wrappers_use_no_private_member_of_the_env():
    offenders = []
    for path in ROOT.glob("wrappers/*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "base":
                if node.attr.startswith("_"):
                    offenders.append(f"{path.name}:{node.lineno} base.{node.attr}")
    assert offenders == []


def test_each_town_names_its_idm_profile_and_the_world_applies_it():
    from highway_env.vehicle.behavior import IDMVehicle

    assert {t: s.idm for t, s in TOWN_SPECS.items()} == {t: "intersection" if t == "intersection" else "default"
                                                         for t in TOWN_SPECS}  # fmt: skip
    for town in ("intersection", "highway", "intersection"):
        apply_idm_profile(town)
        assert {k: getattr(IDMVehicle, k) for k in IDM_PROFILES["default"]} == IDM_PROFILES[TOWN_SPECS[town].idm]
    with pytest.raises(ValueError, match="idm must be one of"):
        TownSpec("HighwayEnv", {}, "freeway", idm="rally")


def test_the_world_surface_reports_the_ego_and_the_clock():
    world = TrafficWorld("merge", simulation_frequency=20, keyframe_frequency=10)
    world.reset(seed=3)
    assert (world.tick, world.time) == (0, 0.0) and world.accelerated and not world.ego_crashed
    world.step(1)
    assert world.tick == 2 and world.time == pytest.approx(0.1)  # two 20 Hz sub-steps per 10 Hz keyframe
    state = world.vehicle_state()
    assert world.vehicle_count == len(state) and world.ego_speed == pytest.approx(np.linalg.norm(state.velocities[0]))
    assert TrafficWorld("merge", traffic="reference").accelerated is False
    world.close()


def test_highway_env_config_is_the_towns_config_with_fog_gyms_frequencies_and_overrides():
    c = highway_env_config("highway", 15, 5, {"vehicles_count": 7})
    assert c["vehicles_count"] == 7 and c["lanes_count"] == 4 and (c["simulation_frequency"], c["policy_frequency"]) == (15, 5)
    assert TOWN_SPECS["highway"].config["vehicles_count"] == 40  # the spec itself is never modified
    with pytest.raises(ValueError, match="town must be one of"):
        highway_env_config("monaco")


def test_episode_seed_for_is_what_reset_draws():
    env = FogDriveEnv(town="merge", resolution=(16, 12), cameras=["CAM_FRONT"])
    for seed in (0, 7, 2**31 + 5):
        env.reset(seed=seed)
        assert env.episode_seed == FogDriveEnv.episode_seed_for(seed)
    env.close()


def test_ground_truth_with_labels_equals_an_env_built_with_them_and_leaves_the_config_alone():
    camera_rule = LabelConfig(visibility="camera")
    a = FogDriveEnv(town="highway", resolution=(64, 48))
    b = FogDriveEnv(town="highway", resolution=(64, 48), labels=camera_rule)
    for env in (a, b):
        env.reset(seed=2)
        env.step(env.idle_action)
    before = a.config
    once, built = a.ground_truth(labels=camera_rule), b.ground_truth()
    assert a.config is before and a.config.labels == LabelConfig()
    for cam in built["boxes_2d"]:
        for key in ("bboxes", "vehicle_ids"):
            np.testing.assert_array_equal(once["boxes_2d"][cam][key], built["boxes_2d"][cam][key])
    np.testing.assert_array_equal(once["boxes_3d"]["corners"], built["boxes_3d"]["corners"])
    with pytest.raises(ValueError, match="labels must be a LabelConfig"):
        a.ground_truth(labels="camera")
    c = FogDriveEnv(config=replace(a.config, labels=None))
    c.reset(seed=2)
    with pytest.raises(ValueError, match="labels=None"):
        c.ground_truth()
    assert c.ground_truth(labels=camera_rule)["boxes_3d"]["corners"].shape[1:] == (8, 3)
    for env in (a, b, c):
        env.close()


#: Names that hold a FogDriveEnv, its unwrapped base, its world or its sensors in wrappers and scripts.
_ENV_HOLDERS = {"env", "base", "world", "unwrapped", "point_sensors", "cameras"}


@pytest.mark.parametrize("folder", ["wrappers", "scripts"])
def test_wrappers_and_scripts_read_no_private_attribute_of_the_env_world_or_sensors(folder):
    offenders = []
    for path in sorted((ROOT / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")):
                continue
            holder = node.value.id if isinstance(node.value, ast.Name) else getattr(node.value, "attr", None)
            if holder in _ENV_HOLDERS:
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} {holder}.{node.attr}")
    assert offenders == []
