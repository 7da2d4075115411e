"""A frame's camera noise on the background thread (CameraEffects.begin, NoiseJob): the same images as one kernel
launch, whichever threads take its tasks; the env's step returns what the sensor records; errors reach the caller."""

from __future__ import annotations

import multiprocessing
import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fog_gym.sensors.camera_effects as effects
import fog_gym.sensors.camera_noise as camera_noise
from fog_gym._numba import background, in_worker
from fog_gym.envs.fogdrive import FogDriveEnv
from fog_gym.geometry import Pose
from fog_gym.sensors.camera import CameraConfig
from fog_gym.sensors.camera_effects import CameraEffects
from fog_gym.sensors.camera_noise import DEFAULT_NOISE, NoiseJob, add_noise_many, noise_law


@settings(max_examples=15, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 60), st.integers(1, 60), st.booleans()), min_size=1, max_size=4),
       st.integers(1, 3), st.integers(0, 2**32))  # fmt: skip
def test_a_job_shared_by_threads_gives_the_bits_of_one_launch(shapes, threads, seed):
    rng = np.random.default_rng(seed)
    day, night = noise_law(DEFAULT_NOISE, 1.0, False), noise_law(DEFAULT_NOISE, 3.0, True)
    imgs = [rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for h, w, _ in shapes]
    laws = [day if gauss else night for _, _, gauss in shapes]
    keys = [int(k) for k in rng.integers(0, 2**63, len(imgs))]
    job = NoiseJob(imgs, laws, keys)
    workers = [threading.Thread(target=job.work) for _ in range(threads)]
    for w in workers:
        w.start()
    job.work()
    for w in workers:
        w.join()
    assert all((a == b).all() for a, b in zip(job.outs, add_noise_many(imgs, laws, keys)))


def _effects() -> CameraEffects:
    cams = [CameraConfig(n, Pose(1.8, 0, 1.2), 40, 30, noise="default") for n in ("CAM_FRONT", "CAM_BACK")]
    return CameraEffects(cams)


@pytest.mark.parametrize("night", [False, True])
@pytest.mark.parametrize("variant", [0, 5])
def test_a_begun_recording_equals_apply_all(monkeypatch, night, variant):
    monkeypatch.setattr(effects, "OVERLAP_FROM", 1)  # small images on the background thread too
    rng = np.random.default_rng(3)
    images = {n: rng.integers(0, 256, (30, 40, 3), dtype=np.uint8) for n in ("CAM_FRONT", "CAM_BACK")}
    exposure = {"CAM_FRONT": 2.0, "CAM_BACK": 5.5}
    a, b = _effects(), _effects()
    a.prepare(9, 4, exposure, night)
    b.prepare(9, 4, exposure, night)
    finish = a.begin(images, variant)
    want = b.apply_all(images, variant)
    got = finish()
    assert set(got) == set(want) and all((got[n] == want[n]).all() for n in want)
    assert all((got[n] != images[n]).any() for n in images)  # noise was drawn
    assert all((a.apply(n, images[n], variant) == want[n]).all() for n in images)  # the laws stay for the variants


def _takers(monkeypatch) -> list[str]:
    """The names of the threads that take a NoiseJob's tasks from now on (appended as they take them)."""
    takers: list[str] = []
    work = NoiseJob.work

    def spy(self):
        takers.append(threading.current_thread().name)
        return work(self)

    monkeypatch.setattr(camera_noise.NoiseJob, "work", spy)
    return takers


def test_frames_overlap_their_noise_from_overlap_from_pixels_by_day_and_night():
    assert effects.overlaps(effects.OVERLAP_FROM) and not effects.overlaps(effects.OVERLAP_FROM - 1)


@pytest.mark.parametrize("night", [False, True])
def test_a_frame_begun_by_day_or_night_is_drawn_on_the_background_thread_and_equals_apply_all(monkeypatch, night):
    monkeypatch.setattr(effects, "OVERLAP_FROM", 1)
    takers = _takers(monkeypatch)
    rng = np.random.default_rng(4)
    images = {n: rng.integers(0, 256, (30, 40, 3), dtype=np.uint8) for n in ("CAM_FRONT", "CAM_BACK")}
    a, b = _effects(), _effects()
    a.prepare(2, 1, {}, night)
    b.prepare(2, 1, {}, night)
    got, want = a.begin(images, 0)(), b.apply_all(images, 0)
    assert all((got[n] == want[n]).all() for n in want)
    assert any(t.startswith("fog-gym-world") for t in takers)


def test_an_error_on_the_background_thread_reaches_the_caller(monkeypatch):
    monkeypatch.setattr(effects, "OVERLAP_FROM", 1)
    fx = _effects()
    fx.prepare(1, 0, {}, True)  # (a night frame: overlapped on every machine; a day frame only without AVX-512)

    def broken(*args, **kwargs):
        raise RuntimeError("no law")

    monkeypatch.setattr(fx, "laws", broken)
    finish = fx.begin({"CAM_FRONT": np.zeros((30, 40, 3), np.uint8)}, 0)
    with pytest.raises(RuntimeError, match="no law"):
        finish()


def test_the_env_step_draws_its_noise_on_the_background_thread_and_returns_the_recorded_frames(monkeypatch):
    monkeypatch.setattr(effects, "OVERLAP_FROM", 1)
    takers = _takers(monkeypatch)
    for light in ("day", "night"):
        kwargs = dict(town="highway", resolution=(64, 48), cameras=["CAM_FRONT", "CAM_LEFT"], labels=None,
                      camera_noise="default", time_of_day=light)  # fmt: skip
        env, ref = FogDriveEnv(**kwargs), FogDriveEnv(**kwargs)
        obs, _ = env.reset(seed=5)
        ref.reset(seed=5)
        for _ in range(3):
            obs = env.step(env.idle_action)[0]
            ref.step(ref.idle_action)
            want = ref._observe()  # no overlap: one launch on this thread
            for cam in ("CAM_FRONT", "CAM_LEFT"):
                assert (obs[cam] == env.camera_record(cam, env.frames[cam].rgb, 0)).all()
                assert (obs[cam] == want[cam]).all() and (obs[cam] != env.frames[cam].rgb).any()
    assert any(name.startswith("fog-gym-world") for name in takers)


def _child(queue) -> None:
    queue.put(background().submit(in_worker).result(timeout=30))


def test_the_background_thread_is_a_worker_and_a_forked_child_gets_its_own():
    assert background().submit(in_worker).result() and not in_worker()
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_child, args=(queue,))
    child.start()
    child.join(60)
    assert child.exitcode == 0 and queue.get(timeout=5) is True
