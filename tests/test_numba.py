"""Serial twins of the parallel kernels (:func:`fog_gym._numba.serial_twin`) give the same bits as the parallel
kernels: an episode observed with every kernel forced parallel equals the one with every kernel forced serial."""

import gymnasium as gym
import numpy as np
import pytest

import fog_gym  # noqa: F401
import fog_gym._numba
from fog_gym.sensors import raycast


def _episode(monkeypatch, below: int, env_id: str, **kwargs) -> list:
    monkeypatch.setattr(fog_gym._numba, "SERIAL_BELOW", below)
    env = gym.make(env_id, **kwargs)
    obs, _ = env.reset(seed=3)
    frames = [obs]
    for a in (1, 3, 1, 0, 4, 1):
        frames.append(env.step(a)[0])
    env.close()
    return frames


@pytest.mark.parametrize("env_id, kwargs", [
    ("FogDriveRL-v0", {"fog": "dense"}),
    ("FogDrive-v0", {"fog": "moderate", "resolution": (96, 64), "cameras": ["CAM_FRONT", "CAM_BACK"]}),
    ("FogDrive-v0", {"fog": "light", "resolution": (48, 32), "cameras": ["CAM_FRONT"], "time_of_day": "night"}),
])  # fmt: skip
def test_serial_and_parallel_kernels_give_identical_frames(monkeypatch, env_id, kwargs):
    parallel = _episode(monkeypatch, 0, env_id, **kwargs)
    serial = _episode(monkeypatch, 10**12, env_id, **kwargs)
    for p, s in zip(parallel, serial):
        assert p.keys() == s.keys()
        for k in p:
            assert np.array_equal(p[k], s[k]), k


def test_serial_twin_is_a_separate_single_thread_kernel():
    assert raycast._cast_serial is not raycast._cast
    assert raycast._cast_serial.py_func.__qualname__ == "_cast_serial"
    assert raycast._cast.targetoptions.get("parallel") and not raycast._cast_serial.targetoptions.get("parallel")


def _kernels():
    """Every numba kernel of the package: (module, name, dispatcher)."""
    import importlib
    import pkgutil

    from numba.core.registry import CPUDispatcher

    def fail(name: str) -> None:
        raise  # walk_packages skips a package whose import fails; a kernel missing from the scan must say why

    out = []
    for info in pkgutil.walk_packages(fog_gym.__path__, "fog_gym.", onerror=fail):
        if ".experiments." in info.name or info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name, obj in vars(module).items():
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == info.name:
                out.append((info.name, name, obj))
    return out


def test_every_kernel_called_from_python_releases_the_gil():
    """The pixel vector env steps its worlds on threads; a kernel holding the GIL would serialise them."""
    kernels = _kernels()
    assert len(kernels) > 60
    held = [f"{m}.{n}" for m, n, d in kernels
            if d.targetoptions.get("inline") != "always" and not d.targetoptions.get("nogil")]  # fmt: skip
    assert held == []


def test_parallel_options_survive_compilation():
    """numba empties a dict of parallel options (``parallel={"fusion": False}``) when it first compiles the kernel:
    a later signature would be compiled fused and a scan of the options would take the kernel for a serial one
    (seen once: the scan below missed ``_glow_rows`` after the kernel had compiled in the same process). Options go
    as ``ParallelOptions``, which numba copies."""
    from numba.core.cpu import ParallelOptions

    from fog_gym.fog import glow

    assert [f"{m}.{n}" for m, n, d in _kernels() if isinstance(d.targetoptions.get("parallel"), dict)] == []
    options = glow._glow_rows.targetoptions["parallel"]
    assert isinstance(options, ParallelOptions) and options.enabled and not options.fusion
    assert not ParallelOptions(options).fusion and not options.fusion  # copied, not consumed


def test_every_parallel_kernel_is_called_through_pick_or_launch():
    """The workqueue layer aborts the process when two threads launch at once: a worker thread must take a serial
    twin (``pick``) or the launch lock (``launch``). Scans every call of a parallel kernel in the package's source."""
    import re
    from pathlib import Path

    kernels = _kernels()
    parallel = {n for _, n, d in kernels if d.targetoptions.get("parallel") not in (None, False)}
    missing = {"_cast", "_raster_bands", "_shade_pass", "_glow_rows"} - parallel
    assert not missing, (missing, sorted(parallel), sorted({m for m, _, _ in kernels}))
    root = Path(fog_gym.__file__).parent
    bad = []
    for path in root.rglob("*.py"):
        for lineno, line in enumerate(path.read_text().splitlines(), 1):
            code = line.split("#")[0]
            for name in parallel:  # a direct call: ``name(`` (``launch(name)(`` and ``pick(name, twin, n)(`` are not)
                for m in re.finditer(rf"(?<![\w]){re.escape(name)}\(", code):
                    if not re.search(r"def\s+$", code[: m.start()]):
                        bad.append(f"{path.name}:{lineno}: {line.strip()}")
    assert bad == []


def test_a_worker_thread_takes_the_serial_twin_and_the_main_thread_the_parallel_kernel():
    pool = fog_gym._numba.worker_pool(1)
    try:
        assert fog_gym._numba.pick(raycast._cast, raycast._cast_serial, 10**9) is raycast._cast
        picked = pool.submit(fog_gym._numba.pick, raycast._cast, raycast._cast_serial, 10**9).result()
        assert picked is raycast._cast_serial
        assert fog_gym._numba.launch(raycast._cast) is raycast._cast
        assert pool.submit(fog_gym._numba.launch, raycast._cast).result() is not raycast._cast
    finally:
        pool.shutdown()


def test_the_parallel_kernels_run_on_tbb_where_the_package_is_installed_and_survive_a_fork():
    """TBB (fork- and thread-safe, µs launches) is the layer wherever pip's ``tbb`` wheel is installed (Linux x86-64:
    a dependency), unless ``NUMBA_THREADING_LAYER`` says otherwise; a child forked after a parallel kernel ran runs
    one again and gets the same numbers."""
    import importlib.metadata
    import multiprocessing
    import os
    import sys

    import numba

    try:
        importlib.metadata.version("tbb")
        installed = sys.platform.startswith("linux")
    except importlib.metadata.PackageNotFoundError:
        installed = False
    if "NUMBA_THREADING_LAYER" not in os.environ:
        assert fog_gym._numba.threading_layer() == ("tbb" if installed else "workqueue")
    rays = np.random.default_rng(0).normal(size=(20_000, 3))
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    kernel = fog_gym._numba.pick(raycast._cast, raycast._cast_serial, 10**9)
    assert kernel is raycast._cast
    here = _cast_ranges(rays)
    assert numba.threading_layer() == fog_gym._numba.threading_layer() or "NUMBA_THREADING_LAYER" in os.environ
    with multiprocessing.get_context("fork").Pool(1) as pool:
        there = pool.apply(_cast_ranges, (rays,))
    assert np.array_equal(here, there)


def _cast_ranges(rays: np.ndarray) -> np.ndarray:
    """Ranges of ``rays`` from 1.8 m above a flat ground, cast by the parallel kernel."""
    from fog_gym.sensors.raycast import cast_rays

    box = {"centers": np.array([[10.0, 0.0, 1.0], [-6.0, 3.0, 1.5]]), "halves": np.array([[1.0, 2.0, 1.0]] * 2),
           "yaws": np.array([0.0, 0.7])}
    return cast_rays(np.array([0.0, 0.0, 1.8]), rays, 100.0, box).distance
