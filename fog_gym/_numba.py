"""Numba set-up shared by every module with kernels: the threading layer, and a one-line notice when the kernels
must be compiled.

GNU OpenMP, numba's usual pick, aborts a process that forks after a parallel kernel ran; Gymnasium's
AsyncVectorEnv and SB3's SubprocVecEnv fork. The workqueue layer is fork-safe (but not for concurrent kernel
launches from several Python threads). ``NUMBA_THREADING_LAYER`` still overrides. Import this module before
defining a kernel.

Compilation takes about a minute on a laptop CPU and happens once (first run, or after an upgrade): kernels are
cached next to their modules. :func:`cold_kernels` reads numba's cache indexes from disk (it imports no kernel
module) and :func:`announce_compilation` prints the notice once per process when some are missing or stale.

Small workloads (the RL presets' 64×64 camera, a 32-channel LiDAR sweep) run faster on one thread: a parallel
kernel pays a launch per parallel region (tens of µs with workqueue), more than such a frame's work.
:func:`serial_twin` compiles a parallel kernel a second time without ``parallel``; :func:`pick` chooses it below a work
size (:data:`SERIAL_BELOW`). Both give the same bits (tests compare them).

Example:
    >>> isinstance(cold_kernels(), list)
    True
"""

from __future__ import annotations

import os
import pickle
import sys
from pathlib import Path

import numba
from numba import njit

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"


#: Work size (pixels, rays, points) below which the kernels run their serial twin.
SERIAL_BELOW = 16_384


def serial_twin(kernel):
    """``kernel`` (a ``parallel=True`` numba dispatcher) compiled again without ``parallel``, with its other options
    and its own on-disk cache entry (the copy has its own name: numba names cache files after the function)."""
    import types

    f = kernel.py_func
    copy = types.FunctionType(f.__code__, f.__globals__, f.__name__ + "_serial", f.__defaults__, f.__closure__)
    copy.__qualname__ = f.__qualname__ + "_serial"
    copy.__doc__ = f"{f.__name__} on one thread (:func:`fog_gym._numba.serial_twin`)."
    options = {k: v for k, v in kernel.targetoptions.items() if k in ("fastmath", "error_model", "boundscheck")}
    return njit(cache=True, **options)(copy)


def pick(kernel, twin, work: int):
    """``kernel`` for ``work`` pixels, rays or points of at least :data:`SERIAL_BELOW`, else its serial ``twin``."""
    return kernel if work >= SERIAL_BELOW else twin


def drop_stale_caches(root: Path | None = None) -> bool:
    """Delete every numba cache file of the package when a module with kernels changed since they were written.

    numba keys a cached kernel on its own module's source only; a kernel that inlines a function of another module
    (the rasteriser's night shading, the perception kernels' ray caster) would keep running the old code after that
    module changed. A digest of all sources, kept beside the caches, catches it; returns whether caches were dropped.
    """
    import hashlib

    root = root or Path(__file__).resolve().parent
    texts = [p.read_bytes() for p in sorted(root.rglob("*.py")) if "__pycache__" not in p.parts]
    digest = hashlib.sha256(b"".join(t for t in texts if b"njit" in t)).hexdigest()  # the kernels' modules
    marker = root / "__pycache__" / "kernels.digest"
    try:
        if marker.exists() and marker.read_text() == digest:
            return False
        dropped = False
        for cache in root.rglob("__pycache__"):
            for f in [*cache.glob("*.nbi"), *cache.glob("*.nbc")]:
                f.unlink(missing_ok=True)
                dropped = True
        marker.parent.mkdir(exist_ok=True)
        marker.write_text(digest)
        return dropped
    except OSError:  # a read-only install: numba falls back to its own cache folder, nothing to do here
        return False


if os.environ.get("FOG_GYM_KEEP_NUMBA_CACHE", "0") != "1":
    drop_stale_caches()

#: The main kernels (module file relative to the package, function name), the ones every env compiles first.
MAIN_KERNELS = (("render/raster.py", "_raster_bands"), ("sensors/raycast.py", "_cast"), ("fog/camera.py", "_koschmieder"),
                ("fog/lidar.py", "_hahner"), ("labels/boxes.py", "_project_boxes"), ("sensors/lidar.py", "_lidar_points"))  # fmt: skip
_announced = False


def _source_stamp(source: Path):
    """The freshness stamp numba keeps in its cache index for a source file (its own function: the format differs
    between numba versions)."""
    from types import SimpleNamespace

    from numba.core.caching import _SourceFileBackedLocatorMixin

    return _SourceFileBackedLocatorMixin.get_source_stamp(SimpleNamespace(_py_file=str(source)))


def _cached(source: Path, function: str) -> bool:
    """Whether numba's on-disk cache of ``function`` in ``source`` exists and matches the source file's stamp."""
    tag = f"py{sys.version_info.major}{sys.version_info.minor}"
    try:
        want = _source_stamp(source)
    except Exception:  # noqa: BLE001 - a numba without this internal: say nothing rather than guess
        return True
    cache = source.parent / "__pycache__"
    if numba.config.CACHE_DIR:  # NUMBA_CACHE_DIR: numba keeps every cache under it, one folder per source folder
        from numba.core.caching import _CacheLocator

        cache = Path(numba.config.CACHE_DIR) / _CacheLocator.get_suitable_cache_subpath(str(source))
    for index in cache.glob(f"{source.stem}.{function}-*.{tag}.nbi"):
        try:
            with open(index, "rb") as f:
                if pickle.load(f) != numba.__version__:
                    continue
                stamp, overloads = pickle.loads(f.read())
        except Exception:  # noqa: BLE001 - an unreadable index counts as missing
            continue
        if stamp == want and overloads:
            return True
    return False


def cold_kernels() -> list[str]:
    """Names of the main kernels whose on-disk cache is missing or stale (empty when all are cached)."""
    root = Path(__file__).resolve().parent
    return [fn for rel, fn in MAIN_KERNELS if (root / rel).exists() and not _cached(root / rel, fn)]


def announce_compilation() -> None:
    """Print the notice to stderr once per process if some kernel must be compiled."""
    global _announced
    if _announced:
        return
    _announced = True
    if cold_kernels():
        print("fog-gym: compiling kernels (first run only, about a minute)…", file=sys.stderr, flush=True)
