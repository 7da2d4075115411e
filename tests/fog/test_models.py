"""Fog models behind one interface: each equals its physics function, and a new model needs no wrapper edit."""

from __future__ import annotations

import numpy as np

import fog_gym
from fog_gym.fog import fog_images, fog_lidar, parse_fog
from fog_gym.fog.models import MODELS, FogContext, Hahner, Koschmieder, model_for, register_model
from fog_gym.dataset.packing import pack_points, unpack_points
from fog_gym.wrappers import FogWrapper

LEVELS = [parse_fog("light"), parse_fog("dense")]


def test_the_registry_maps_cameras_to_koschmieder_and_lidar_to_hahner():
    assert isinstance(model_for("camera"), Koschmieder) and isinstance(model_for("lidar"), Hahner)
    assert model_for("radar") is None and model_for("semantic_lidar") is None


def test_koschmieder_model_equals_fog_images():
    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 256, (6, 8, 3), dtype=np.uint8)
    depth = rng.uniform(1, 300, (6, 8)).astype(np.float32)
    K, A = np.array([[4.0, 0, 4], [0, 4.0, 3], [0, 0, 1]]), np.array([190.0, 200.0, 210.0])
    out = Koschmieder().apply({"C": rgb, "C_DEPTH": depth}, "C", LEVELS, FogContext({"C": K}, {"C": A}))
    ref = fog_images(rgb, depth, K, [lv.alpha for lv in LEVELS], A)
    for lv, img in zip(LEVELS, ref):
        np.testing.assert_array_equal(out[lv.name], img)


def test_hahner_model_equals_fog_lidar_with_the_levels_generators():
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(-50, 50, (200, 3)), rng.uniform(0, 1, 200)]).astype(np.float32)
    obs = {"LIDAR_TOP": pack_points(pts, 300)}
    ctx = FogContext(rngs={lv.name: np.random.default_rng(i) for i, lv in enumerate(LEVELS)})
    out = Hahner().apply(obs, "LIDAR_TOP", LEVELS, ctx)
    for i, lv in enumerate(LEVELS):
        ref = fog_lidar(pts, lv, np.random.default_rng(i), 10.0)
        np.testing.assert_array_equal(unpack_points(out[lv.name]), ref)


def test_a_new_model_is_a_registered_class_that_the_wrapper_picks_up():
    @register_model("radar")
    class RadarDimming:  # a made-up model: each level scales the radar's depths
        name = "dimming"

        def apply(self, obs, channel, levels, context):
            return {lv.name: obs[channel] * np.float32(0.5) for lv in levels}

    try:
        env = FogWrapper(fog_gym.FogDriveEnv(resolution=(32, 24), cameras=["CAM_FRONT"], episode_seconds=0.2),
                         ["light", "dense"])  # fmt: skip
        obs, _ = env.reset(seed=0)
        np.testing.assert_array_equal(obs["RADAR_FRONT_FOG_DENSE"], obs["RADAR_FRONT"] * np.float32(0.5))
        assert "SEM_LIDAR_TOP_FOG_DENSE" not in obs and "LIDAR_TOP_FOG_DENSE" in obs
        env.close()
    finally:
        MODELS.pop("radar")
