import os

import numpy as np
import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "offscreen")

import fog_gym  # noqa: E402,F401  (registers FogDrive-v0)
from hypothesis import settings  # noqa: E402

# Property tests are deterministic by default: the same examples on every run (derandomize) and no per-example
# deadline (a first example that loads a kernel, or a machine busy with other work, is not a failure).
# HYPOTHESIS_PROFILE=explore draws new examples on every run, for finding cases rather than checking them.
settings.register_profile("default", deadline=None, derandomize=True, print_blob=True)
settings.register_profile("explore", deadline=None, derandomize=False, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


@pytest.fixture(scope="session")
def small_env():
    """A small-resolution highway env, reset with seed 0 (shared; tests must not step it)."""
    from fog_gym.envs.fogdrive import FogDriveEnv

    env = FogDriveEnv(town="highway", resolution=(160, 120))
    env.reset(seed=0)
    yield env
    env.close()


def first_idle(action_space):
    return 1 if action_space.shape == () else np.zeros(action_space.shape, np.float32)


@pytest.fixture(autouse=True)
def _restore_sensor_and_fog_registries():
    """A test (or README example) that registers a sensor class or a fog model leaves the registries as it found
    them (a dataset's channel layout comes from its rig, nothing global to restore)."""
    from fog_gym import sensors
    from fog_gym.fog import models as fog_models

    saved = (dict(sensors.REGISTRY), dict(fog_models.MODELS))
    yield
    for live, old in zip((sensors.REGISTRY, fog_models.MODELS), saved):
        live.clear()
        live.update(old)


def pytest_sessionstart(session):
    """Compile every env path's kernels ahead, in parallel processes, before the first test (a no-op when cached).
    Under pytest-xdist the controller does it before its workers start; the workers then load the cache."""
    if hasattr(session.config, "workerinput"):
        return
    from fog_gym.envs.warmup import PATHS, ensure_compiled

    ensure_compiled(*PATHS)


def pytest_collection_modifyitems(session, config, items):
    """``FOG_GYM_TEST_ORDER=reverse`` or ``shuffle:<seed>`` runs the suite in another order (the hunt for tests that
    depend on order or shared state: ``docs/installation.md``); unset, pytest's order."""
    order = os.environ.get("FOG_GYM_TEST_ORDER", "")
    if not order:
        return
    if order == "reverse":
        items.reverse()
    elif order.startswith("shuffle:") and order[len("shuffle:"):].isdigit():
        import random

        random.Random(int(order[len("shuffle:"):])).shuffle(items)
    else:
        raise pytest.UsageError(f"FOG_GYM_TEST_ORDER must be 'reverse' or 'shuffle:<seed>', got {order!r}")
