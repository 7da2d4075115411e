"""The world's narrow surface: only ``fog_gym/world.py`` (and its traffic core) touches highway-env objects,
towns carry their IDM profile, and the env's ground truth takes a one-call label override."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from fog_gym.env import FogDriveEnv
from fog_gym.labels import LabelConfig
from fog_gym.world import IDM_DEFAULT, IDM_INTERSECTION, TOWN_SPECS, TownSpec, TrafficWorld, scenario_config

ROOT = Path(__file__).resolve().parents[1]
#: The world's own modules: the only ones allowed to reach highway-env objects.
WORLD_MODULES = {ROOT / "fog_gym" / "world.py"}
WORLD_PACKAGES = (ROOT / "fog_gym" / "traffic",)
SCANNED = ("fog_gym", "wrappers", "scripts", "examples", "tests")
#: Names that hold a FogDriveEnv, its unwrapped base or its world in wrappers and scripts.
ENV_NAMES = {"env", "base", "world", "unwrapped"}


def _python_files() -> list[Path]:
    files = set()
    for folder in SCANNED:
        files.update(p.resolve() for p in (ROOT / folder).rglob("*.py"))
    return sorted(files)


def _outside_world(path: Path) -> bool:
    return path not in WORLD_MODULES and not any(path.is_relative_to(p) for p in WORLD_PACKAGES)


def _holder(node: ast.expr) -> str | None:
    """The name an attribute is read from: ``env`` in ``env._x``, ``world`` in ``self.env.world._x``."""
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return None


def test_only_the_world_touches_highway_env_objects():
    offenders = []
    for path in filter(_outside_world, _python_files()):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Attribute) and node.attr == "hw":
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} .hw")
            name = node.attr if isinstance(node, ast.Attribute) else node.id if isinstance(node, ast.Name) else ""
            if name.startswith("_IDM_"):
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} {name}")
    assert offenders == []


@pytest.mark.parametrize("folder", ["wrappers", "scripts"])
def test_wrappers_and_scripts_read_no_private_attribute_of_the_env_or_world(folder):
    offenders = []
    for path in sorted((ROOT / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
                    and _holder(node.value) in ENV_NAMES):  # fmt: skip
                offenders.append(f"{path.relative_to(ROOT)}:{node.lineno} .{node.attr}")
    assert offenders == []


def test_each_town_carries_its_idm_profile():
    assert TOWN_SPECS["intersection"].idm == IDM_INTERSECTION
    assert all(spec.idm == IDM_DEFAULT for town, spec in TOWN_SPECS.items() if town != "intersection")
    assert IDM_DEFAULT["DISTANCE_WANTED"] == 10.0 and IDM_INTERSECTION["DISTANCE_WANTED"] == 7.0


def test_a_world_applies_its_towns_idm_profile_before_stepping():
    from highway_env.vehicle.behavior import IDMVehicle

    worlds = [TrafficWorld(town, episode_seconds=1.0) for town in ("intersection", "highway", "intersection")]
    for world in worlds:
        world.reset(seed=0)
    for world in worlds:  # interleaved: each step restores the stepping world's own profile
        world.step(1)
        assert world.idm_profile is TOWN_SPECS[world.town].idm
        assert {k: getattr(IDMVehicle, k) for k in IDM_DEFAULT} == dict(world.idm_profile)
        world.close()


def test_a_town_spec_rejects_an_idm_profile_with_unknown_keys():
    with pytest.raises(ValueError, match="idm must be a mapping"):
        TownSpec("HighwayEnv", {}, "freeway", {"DISTANCE_WANTED": 5.0, "TIME_WANTED": 1.0})


def test_scenario_config_is_the_config_the_world_runs():
    world = TrafficWorld("exit", simulation_frequency=15, keyframe_frequency=5, highway_config={"lanes_count": 3})
    expected = scenario_config("exit", 15, 5, {"lanes_count": 3})
    running = world.scenario_config
    assert {k: running[k] for k in expected} == expected
    assert expected["vehicles_count"] == 30 and expected["policy_frequency"] == 5
    running["lanes_count"] = 9  # a copy: the world's scenario is untouched
    assert world.scenario_config["lanes_count"] == 3
    world.close()
    with pytest.raises(ValueError, match="town must be one of"):
        scenario_config("nowhere")


def test_world_surface_reports_tick_seed_and_ego_state():
    env = FogDriveEnv(town="highway", resolution=(16, 12), cameras=["CAM_FRONT"], labels=None)
    _, info = env.reset(seed=4)
    world = env.world
    assert world.seed == env.episode_seed and world.tick == 0
    substeps = world.simulation_frequency // world.keyframe_frequency
    for k in range(1, 4):
        _, _, _, _, info = env.step(env.idle_action)
        assert world.tick == k * substeps
        assert info["speed"] == world.ego_speed and info["crashed"] == world.ego_crashed is False
        assert world.vehicle_count == len(world.vehicle_state())
    env.close()


@pytest.mark.parametrize("visibility", ["lidar", "camera"])
def test_ground_truth_override_equals_an_env_built_with_those_labels(visibility):
    kwargs = dict(town="merge", resolution=(64, 48), cameras=["CAM_FRONT", "CAM_BACK"])
    labels = LabelConfig(visibility=visibility)
    env, ref = FogDriveEnv(**kwargs), FogDriveEnv(**kwargs, labels=labels)
    config = env.config
    for e in (env, ref):
        e.reset(seed=2)
        e.step(e.idle_action)
    got, want = env.ground_truth(labels=labels), ref.ground_truth()
    assert env.config is config  # untouched: the override lives for the one call
    assert got.keys() == want.keys() and got["boxes_2d"].keys() == want["boxes_2d"].keys()
    for key in ("boxes_3d", *(f"boxes_2d/{c}" for c in want["boxes_2d"])):
        g, w = (d["boxes_2d"][key.split("/")[1]] if "/" in key else d[key] for d in (got, want))
        assert g.keys() == w.keys()
        for field in w:
            np.testing.assert_array_equal(np.asarray(g[field]), np.asarray(w[field]), err_msg=f"{key}.{field}")
    for group in ("intrinsics", "extrinsics"):
        for name in want[group]:
            np.testing.assert_array_equal(got[group][name], want[group][name])


def test_ground_truth_rejects_a_label_override_of_the_wrong_type():
    env = FogDriveEnv(town="merge", resolution=(16, 12), cameras=["CAM_FRONT"], labels=None)
    env.reset(seed=0)
    with pytest.raises(TypeError, match="labels must be a LabelConfig"):
        env.ground_truth()
    with pytest.raises(TypeError, match="labels must be a LabelConfig"):
        env.ground_truth(labels="camera")
    assert env.ground_truth(labels=LabelConfig())["boxes_3d"] is not None and env.config.labels is None


def test_env_public_surface_matches_its_rig():
    env = FogDriveEnv(town="merge", resolution=(32, 24), cameras=["CAM_BACK", "CAM_FRONT"])
    assert env.camera_names == ("CAM_BACK", "CAM_FRONT")
    k = env.intrinsics
    assert set(k) == set(env.camera_names) and all(m.shape == (3, 3) for m in k.values())
    k["CAM_FRONT"][0, 0] = -1.0  # a copy
    assert env.intrinsics["CAM_FRONT"][0, 0] > 0
