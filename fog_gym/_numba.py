"""Numba set-up shared by every module with kernels: the threading layer, serial twins, and compiling ahead.

GNU OpenMP, numba's usual pick, aborts a process that forks after a parallel kernel ran; Gymnasium's
AsyncVectorEnv and SB3's SubprocVecEnv fork. The threading layer is Intel TBB (the ``tbb`` package, a dependency on
Linux x86-64), which is fork- and thread-safe and wakes its threads in about a microsecond; where TBB cannot be loaded,
the workqueue layer, which is fork-safe but not for concurrent kernel launches from several Python threads, and on a
virtual machine can take hundreds of µs to wake an idle core's thread at every parallel launch
(:func:`threading_layer` says which; ``docs/performance.md``, "The threading layer"). ``NUMBA_THREADING_LAYER``
still overrides. Import this module before defining a kernel.

Kernels compile once (first run, or after an upgrade) and are cached next to their modules. An env compiles the
kernels of its path ahead, in parallel worker processes, with a progress bar that names them
(:func:`compile_kernels`, the paths in :mod:`fog_gym.envs.kernel_table`); a kernel compiled on its first call
instead is named on stderr.

Small workloads (the RL presets' 64×64 camera, their sweep's fog) run faster on one thread: a parallel kernel pays a
launch per parallel region (tens of µs with workqueue), more than such a frame's work. :func:`serial_twin` compiles a
parallel kernel a second time without ``parallel``; :func:`pick` chooses it below a work size (:data:`SERIAL_BELOW`,
or the kernel's own: the ray cast, whose rays cost far more than pixels, from 8 192 rays). Both give the same bits
(tests compare them).

**Kernels release the GIL** (``nogil=True``, every kernel; a test checks it), so several threads run kernels at once:
the pixel vector env's worlds hand theirs to a crew of threads in rounds (:mod:`fog_gym._rounds`; :func:`pick`'s twin
and :func:`defer`'s kernel wait for the round in a world's step), the camera noise runs on :func:`background`. The
workqueue layer is not thread safe: in a worker thread
:func:`pick` always takes the serial twin, and a parallel kernel without one is called through :func:`launch`, which
holds the process's launch lock there (a test checks every call site).

Example:
    >>> parse_signature(("float64", "int64"))
    (float64, int64)
"""

from __future__ import annotations

import os
import sys
import threading
from pathlib import Path
from typing import NamedTuple

import numba
import numpy as np
from numba import njit
from numba.core import event as _event

from fog_gym import _rounds


def _load_tbb() -> bool:
    """Whether numba's TBB layer can be loaded here. pip's ``tbb`` wheel puts ``libtbb.so.12`` in the environment's
    ``lib`` folder, outside the loader's search path, so it is loaded by its path first (into the global namespace,
    where numba's ``tbbpool`` extension then finds it)."""
    import ctypes

    if not sys.platform.startswith("linux"):
        return False
    for folder in dict.fromkeys((sys.prefix, sys.base_prefix, sys.exec_prefix)):
        lib = Path(folder) / "lib" / "libtbb.so.12"
        if lib.is_file():
            try:
                ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
            except OSError:
                continue
            break
    try:
        from numba.np.ufunc import parallel, tbbpool  # noqa: F401

        parallel._check_tbb_version_compatible()
    except (ImportError, OSError, AttributeError):
        return False
    return True


_TBB = _load_tbb()  # (also where NUMBA_THREADING_LAYER asks for "tbb" or "safe": numba then finds the library)
if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "tbb" if _TBB else "workqueue"


def threading_layer() -> str:
    """The threading layer numba's parallel kernels run on in this process: ``"tbb"``, ``"workqueue"`` (TBB could
    not be loaded) or what ``NUMBA_THREADING_LAYER`` asked for.

    >>> threading_layer() in ("tbb", "workqueue", "omp", "safe", "forksafe", "threadsafe", "default")
    True
    """
    return str(numba.config.THREADING_LAYER)


#: The fast-math flags of the pixel kernels: all of LLVM's but reassociation, so a vectorised loop and its scalar
#: remainder add in the same order and a pixel's value does not depend on where its row starts in memory.
FASTMATH = {"nnan", "ninf", "nsz", "arcp", "contract", "afn"}

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
    kept = ("fastmath", "error_model", "boundscheck", "nogil")
    options = {k: v for k, v in kernel.targetoptions.items() if k in kept}
    return njit(cache=True, **options)(copy)


def pick(kernel, twin, work: int, below: int = SERIAL_BELOW):
    """``kernel`` for ``work`` pixels, rays or points of at least ``below`` (default :data:`SERIAL_BELOW`; a kernel
    with less work per item passes its own), else its serial ``twin`` (and always the twin in a
    :func:`worker_pool`'s thread); in a world's step that :func:`fog_gym._rounds.run_rounds` runs, the twin waits for
    the round (:func:`defer`)."""
    if work >= below and not _THREAD.worker:
        return kernel
    return _rounds.deferred(twin) if _rounds.deferring() else twin


def defer(kernel):
    """``kernel`` itself; in a world's step that :func:`fog_gym._rounds.run_rounds` runs, a call that waits for the
    round: the other worlds run to their next kernel, then the round's kernels run on the crew's threads.

    >>> f = njit(lambda x: x + 1)
    >>> defer(f) is f
    True
    """
    return _rounds.deferred(kernel) if _rounds.deferring() else kernel


class _ThreadState(threading.local):
    worker = False  # a worker_pool thread: serial kernels only, parallel launches under _LAUNCH


_THREAD = _ThreadState()
_LAUNCH = threading.Lock()


def launch(kernel):
    """``kernel`` (a parallel kernel without a serial twin), to call: in a :func:`worker_pool` thread, a function that
    calls it holding the process's launch lock, since numba's workqueue layer must not launch from two threads at
    once; elsewhere the kernel itself.

    >>> f = njit(lambda x: x + 1)
    >>> launch(f) is f, worker_pool(1).submit(lambda: launch(f)(1)).result()
    (True, 2)
    """
    if not _THREAD.worker:
        return kernel

    def locked(*args):
        with _LAUNCH:
            return kernel(*args)

    return locked


def _mark_worker() -> None:
    _THREAD.worker = True


def in_worker() -> bool:
    """Whether this thread is a :func:`worker_pool`'s (its kernels run their serial twins)."""
    return bool(_THREAD.worker)


def worker_pool(threads: int):
    """A ``ThreadPoolExecutor`` of ``threads`` threads marked as workers (:func:`pick` and :func:`launch` keep
    numba's threading layer to one launch at a time)."""
    from concurrent.futures import ThreadPoolExecutor

    return ThreadPoolExecutor(max_workers=threads, thread_name_prefix="fog-gym-world", initializer=_mark_worker)


def worker_crew(threads: int) -> _rounds.Crew:
    """A :class:`fog_gym._rounds.Crew` of ``threads`` whose helpers are marked as workers (:func:`pick` and
    :func:`launch` keep numba's threading layer to one launch at a time).

    >>> crew = worker_crew(2); from fog_gym._rounds import _Call
    >>> both = threading.Barrier(2, timeout=10)
    >>> crew.run([_Call(lambda: both.wait() * 0 + in_worker(), ())] * 2) in ([False, True], [True, False])
    True
    >>> crew.close()
    """
    return _rounds.Crew(threads, _mark_worker)


_BACKGROUND: tuple[int, object] | None = None


def background():
    """The process's background thread (a :func:`worker_pool` of one, so its kernels run their serial twins): work
    whose result the caller needs only later — a frame's camera noise while the env computes its points and labels —
    overlaps the caller's own. A forked child gets a thread of its own (a parent's thread does not survive a fork).

    >>> background().submit(lambda: in_worker()).result(), in_worker()
    (True, False)
    """
    global _BACKGROUND
    if _BACKGROUND is None or _BACKGROUND[0] != os.getpid():
        _BACKGROUND = (os.getpid(), worker_pool(1))
    return _BACKGROUND[1]


def readonly(a):
    """A read-only view of ``a`` (no copy). Kernels take the arrays that may be read-only (cached ray patterns) as
    read-only views, so numba compiles one signature for them, not one for each writability.

    >>> readonly(np.zeros(2)).flags.writeable
    False
    """
    view = a.view()
    view.flags.writeable = False
    return view


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



# -- compiling ahead, in parallel processes, with progress ----------------------------------------------------------
#
# A kernel compiles on its first call with new argument types; the paths of fog-gym (an env preset at its sizes)
# call a known set of kernels with known types, listed per path in :mod:`fog_gym.envs.kernel_table` (made by
# ``scripts/kernel_table.py`` from real runs, checked by the tests). :func:`compile_kernels` compiles the entries whose
# on-disk cache is missing or stale, each kernel in a worker process (longest first, as many processes as cores),
# and shows a progress bar naming them; the calling process then loads every kernel from the cache. A kernel a
# path calls that the table misses still compiles on its first call, and :func:`_CompileNotices` names it.


class KernelEntry(NamedTuple):
    """One kernel of a path: its module, its name in the module, the argument types of each signature the path
    compiles (numba type reprs, e.g. ``"Array(float64, 2, 'C', False, aligned=True)"``), and the seconds its
    compilation took when the table was made (to start the longest first)."""

    module: str
    name: str
    signatures: tuple[tuple[str, ...], ...]
    seconds: float

    @property
    def label(self) -> str:
        """``render.raster._raster_bands``: the kernel's name without the package."""
        return f"{self.module.removeprefix('fog_gym.')}.{self.name}"


def _types_namespace() -> dict:
    from numba.core import types

    return {**vars(types), "bool": types.boolean, "none": types.none}


def parse_signature(argtypes: tuple[str, ...]) -> tuple:
    """numba types from their reprs (what :class:`KernelEntry` stores).

    >>> parse_signature(("float64", "Array(int32, 1, 'C', False, aligned=True)", "bool"))
    (float64, Array(int32, 1, 'C', False, aligned=True), bool)
    """
    ns = _types_namespace()
    return tuple(eval(t, {"__builtins__": {}}, ns) for t in argtypes)  # noqa: S307 - reprs of numba types only


def _dispatcher(module: str, name: str):
    import importlib

    return getattr(importlib.import_module(module), name)


def _missing(entry: KernelEntry) -> tuple[tuple[str, ...], ...]:
    """The signatures of ``entry`` that numba's on-disk cache lacks (or holds for another source or machine)."""
    try:
        disp = _dispatcher(entry.module, entry.name)
        cache = disp._cache  # numba's per-function cache: its index maps (signature, machine, code hash) to a file
        if not hasattr(cache, "_cache_file"):  # caching off (cache=False): nothing to compile ahead
            return ()
        codegen = disp.targetctx.codegen()
        keys = cache._cache_file._load_index().keys()
        missing = []
        arity = disp.py_func.__code__.co_argcount
        for sig in entry.signatures:
            if len(sig) != arity:  # the table is older than the kernel: its first call compiles it (and is named)
                continue
            key = cache._index_key(parse_signature(sig), codegen)
            if key not in keys:
                missing.append(sig)
        return tuple(missing)
    except Exception:  # noqa: BLE001 - a numba whose internals differ, a kernel renamed: leave it to the first call
        return ()


def cold(entries: list[KernelEntry]) -> list[KernelEntry]:
    """The entries with a signature to compile, each reduced to its missing signatures."""
    out = []
    for e in entries:
        missing = _missing(e)
        if missing:
            out.append(e._replace(signatures=missing))
    return out


def _compile_entry(module: str, name: str, signatures: tuple[tuple[str, ...], ...]) -> float:
    """Compile (and cache) one kernel's signatures; the worker process's task. Returns the seconds it took."""
    import time

    _CompileNotices.on = False  # compiled on purpose, behind the caller's progress bar
    t0 = time.perf_counter()
    disp = _dispatcher(module, name)
    for sig in signatures:
        disp.compile(parse_signature(sig))
    return time.perf_counter() - t0


def compile_jobs() -> int:
    """Worker processes for :func:`compile_kernels`: ``FOG_GYM_COMPILE_JOBS`` or the CPUs this process may use."""
    env = os.environ.get("FOG_GYM_COMPILE_JOBS")
    if env:
        return max(1, int(env))
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _bins(entries: list[KernelEntry], jobs: int) -> list[list[KernelEntry]]:
    """``entries`` (longest first) dealt to ``jobs`` workers, each to the least loaded one (by recorded seconds)."""
    bins: list[list[KernelEntry]] = [[] for _ in range(jobs)]
    load = [0.0] * jobs
    for e in entries:
        k = load.index(min(load))
        bins[k].append(e)
        load[k] += max(e.seconds, 0.1)
    return [b for b in bins if b]


def _compile_worker() -> None:
    """A worker process of :func:`compile_kernels`: reads its entries as JSON from stdin and reports ``start``,
    ``done`` or ``error`` per kernel on stdout, one JSON line each."""
    import json

    for module, name, sigs, seconds in json.loads(sys.stdin.read()):
        label = KernelEntry(module, name, (), 0.0).label
        print(json.dumps(["start", label]), flush=True)
        try:
            _compile_entry(module, name, tuple(tuple(s) for s in sigs))
            print(json.dumps(["done", label]), flush=True)
        except Exception as e:  # noqa: BLE001 - reported; the kernel then compiles on its first call
            print(json.dumps(["error", label, f"{type(e).__name__}: {e}".splitlines()[0][:300]]), flush=True)


def compile_kernels(entries: list[KernelEntry], jobs: int | None = None, file=None) -> list[KernelEntry]:
    """Compile the cold ``entries`` ahead of their first call, in ``jobs`` worker processes (default
    :func:`compile_jobs`), longest first, with a progress bar on ``file`` (stderr) that names the kernels; returns the
    entries it compiled (none when everything is cached). ``FOG_GYM_COMPILE=lazy`` turns this off (kernels then
    compile on their first call, one after the other).

    The workers are fresh interpreters (``python -c``), not ``multiprocessing`` children, so a user's script without
    an ``if __name__ == "__main__":`` guard is never imported again. A kernel a worker cannot compile is named on
    ``file`` and compiles on its first call instead."""
    import json
    import queue
    import subprocess
    import threading
    import time

    from tqdm import tqdm

    if os.environ.get("FOG_GYM_COMPILE", "ahead") == "lazy":
        return []
    todo = sorted(cold(list(dict.fromkeys(entries))), key=lambda e: -e.seconds)
    if not todo:
        return []
    bins = _bins(todo, min(jobs or compile_jobs(), len(todo)))
    file = sys.stderr if file is None else file
    tty = hasattr(file, "isatty") and file.isatty()
    tick = 1.0 if tty else 5.0  # a log file gets a line every 5 s, a terminal one line redrawn every second
    n = len(bins)
    bar = tqdm(total=len(todo), desc=f"fog-gym: compiling kernels (first run only, {n} process{'es' * (n > 1)})",
               unit="kernel", file=file, mininterval=tick, bar_format="{desc}: {n}/{total} [{elapsed}]{postfix}")
    events: queue.Queue = queue.Queue()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p), "FOG_GYM_COMPILE_NOTICES": "0"}
    procs = []
    t0 = time.perf_counter()
    try:
        for b in bins:
            proc = subprocess.Popen([sys.executable, "-c", "from fog_gym._numba import _compile_worker; _compile_worker()"],
                                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                                    env=env)  # fmt: skip
            proc.stdin.write(json.dumps([list(e) for e in b]))
            proc.stdin.close()
            procs.append(proc)
            threading.Thread(target=lambda p=proc: [events.put(json.loads(line)) for line in p.stdout] + [events.put(None)],
                             daemon=True).start()  # fmt: skip
        running: dict[str, None] = {}
        finished = 0
        errors = []
        while finished < len(procs):
            try:
                ev = events.get(timeout=tick)
            except queue.Empty:
                bar.refresh()
                continue
            if ev is None:
                finished += 1
                continue
            if ev[0] == "start":
                running[ev[1]] = None
            else:
                running.pop(ev[1], None)
                bar.update()
                if ev[0] == "error":
                    errors.append(f"{ev[1]} ({ev[2]})")
            bar.set_postfix_str(", ".join(running), refresh=True)
        for proc in procs:
            proc.wait()
        bar.set_postfix_str(f"done in {time.perf_counter() - t0:.0f} s")
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
        bar.close()
    for err in errors:
        print(f"fog-gym: could not compile {err} ahead; it compiles on its first call", file=file, flush=True)
    return todo


class _CompileNotices(_event.Listener):
    """A numba event listener that names each fog-gym kernel compiled on its first call (one the compile table
    missed) on stderr."""

    #: Off in the worker processes of :func:`compile_kernels` (the caller's progress bar names their kernels).
    on = True

    def __init__(self) -> None:
        super().__init__()
        self.depth = 0
        self.start = 0.0

    def on_start(self, event) -> None:
        import time

        self.depth += 1
        if self.depth == 1:
            self.start = time.perf_counter()
            f = event.data["dispatcher"].py_func
            if self.on and f.__module__.startswith("fog_gym"):
                print(f"fog-gym: compiling {f.__module__.removeprefix('fog_gym.')}.{f.__name__} …", file=sys.stderr,
                      flush=True)  # fmt: skip

    def on_end(self, event) -> None:
        self.depth -= 1


if os.environ.get("FOG_GYM_COMPILE_NOTICES", "1") == "1":
    _event.register("numba:compile", _CompileNotices())
