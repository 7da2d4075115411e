"""Perceived objects in a fog field: the LiDAR keeps a return exactly when the fog model keeps that point, the camera
sees through the field's transmittance, a bank beyond every vehicle changes nothing and a bank over everything is the
homogeneous fog of its visibility."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import fog_gym  # noqa: F401  (registers the envs)
from fog_gym.fog.depth import field_pose
from fog_gym.fog.fields import FogBank, HeightFog
from fog_gym.fog.lidar_field import (FIELD_COARSE, FIELD_STEP, field_keeps, field_pulse_weights, fog_lidar_field,
                                     peak_extinction)  # fmt: skip

LIDAR = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 1.8], [0, 0, 0, 1.0]])


@pytest.mark.parametrize("field", [FogBank(40.0, 30.0, 60.0), FogBank(25.0, -20.0, 60.0, edge=0.0),
                                   HeightFog(40.0, 4.0) + FogBank(60.0, 40.0, 30.0)])  # fmt: skip
def test_field_keeps_makes_the_fog_models_decision_on_the_same_ray(field):
    rng = np.random.default_rng(3)
    r = rng.uniform(3.0, 110.0, 400)
    az, el = rng.uniform(-0.8, 0.8, r.size), rng.uniform(-0.05, 0.02, r.size)
    d = np.c_[np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)]
    pts = np.c_[r[:, None] * d, np.exp(-0.004 * r)].astype(np.float32)  # CARLA's intensities, as perception uses
    pose = field_pose(LIDAR, (0.0, 0.0, 0.0))
    kept_model = np.all(fog_lidar_field(pts, field, np.random.default_rng(0), pose, noise=0.0)[:, :3] == pts[:, :3], axis=1)
    terms = field.pack()
    w = (*field_pulse_weights(), *field_pulse_weights(FIELD_STEP * FIELD_COARSE))
    r32 = np.linalg.norm(pts[:, :3].astype(np.float64), axis=1)
    unit = pts[:, :3].astype(np.float64) / r32[:, None]
    kept = np.array([field_keeps(r32[i], float(pts[i, 3]), terms, pose[0], pose[1], unit[i, 0], unit[i, 2], *w,
                                 peak_extinction(terms)) for i in range(len(pts))])  # fmt: skip
    assert np.array_equal(kept, kept_model) and 0.05 < kept.mean() < 0.95


def _run(env_id, steps=6, seed=11, **kwargs):
    env = gym.make(env_id, observation="objects", **kwargs)
    out = [env.reset(seed=seed)[0]]
    counts = []
    for _ in range(steps):
        obs, _, term, trunc, info = env.step(1)
        out.append(obs)
        counts.append({s: int(info["detections"][s]["count"]) for s in ("camera", "lidar", "radar", "fused")})
    env.close()
    return np.array(out), counts


def test_a_bank_beyond_every_vehicle_changes_nothing_and_a_bank_over_everything_is_the_homogeneous_fog():
    from fog_gym.fog.banks import BankConfig

    far = BankConfig(start=(5000.0, 5000.0), length=(100.0, 100.0), visibility=(30.0, 30.0), edge=(0.0, 0.0))
    clear_obs, clear_counts = _run("FogDriveRLHazard-v0", fog="clear")
    far_obs, far_counts = _run("FogDriveRLFogBank-v0", banks=far)
    assert np.array_equal(far_obs, clear_obs) and far_counts == clear_counts
    # (a bank's start is drawn >= 0 by BankConfig: one over everything goes through fog=)
    flat_obs, flat_counts = _run("FogDriveRLHazard-v0", fog=30.0)
    bank_obs, bank_counts = _run("FogDriveRLHazard-v0", fog=FogBank(30.0, -5000.0, 10_000.0, edge=0.0))
    assert bank_counts == flat_counts and np.allclose(bank_obs, flat_obs, atol=1e-5)
    assert flat_counts != clear_counts  # (the fog matters in this scene)


def test_the_same_seed_draws_the_same_bank_for_pixels_and_objects_and_the_vector_env_matches_single_envs():
    pixels = gym.make("FogDriveRLFogBank-v0")
    objects = gym.make("FogDriveRLFogBank-v0", observation="objects")
    assert pixels.reset(seed=5)[1]["fog"] == objects.reset(seed=5)[1]["fog"]
    vec = gym.make_vec("FogDriveRLFogBank-v0", num_envs=2, vectorization_mode="vector_entry_point",
                       observation="objects")  # fmt: skip
    vobs, vinfo = vec.reset(seed=5)
    sobs = [gym.make("FogDriveRLFogBank-v0", observation="objects").reset(seed=s)[0] for s in (5, 6)]
    assert np.array_equal(vobs, np.stack(sobs))
    for e in (pixels, objects, vec):
        e.close()
