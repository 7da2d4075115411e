"""The kernels each env path calls, compiled ahead in parallel processes (:func:`fog_gym._numba.compile_kernels`).

A *path* is what an env of one kind runs at its sizes: ``fogdrive`` (FogDrive-v0's full rig by day, paired fog,
labels, render), ``fogdrive-night`` (the same by night), ``rl-pixels`` (the RL presets' 64×64 camera and LiDAR image),
``rl-objects`` (their perceived objects) and ``vector`` (their native vector envs). :data:`PATHS` runs each one;
:mod:`fog_gym.envs.kernel_table` lists the kernels and argument types each compiles, recorded from those runs by
``scripts/kernel_table.py`` (``python -m fog_gym.envs.warmup --record PATH`` records one). An env calls
:func:`ensure_compiled` for its path when it is built: on a cold cache the path's kernels compile in worker processes,
longest first, behind a progress bar that names them. The tests check that every path's kernels and types are in the
table, so a kernel the table misses shows up there, not as a silent first-call compilation.

Example:
    >>> sorted(PATHS) == sorted(TABLE)
    True
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Callable

from fog_gym._numba import KernelEntry, compile_kernels
from fog_gym.envs.kernel_table import TABLE


def _episode(env_id: str, steps: int = 2, render: bool = False, **kwargs) -> None:
    import gymnasium as gym

    env = gym.make(env_id, render_mode="rgb_array" if render else None, **kwargs)
    env.reset(seed=0)
    for _ in range(steps):
        env.step(env.unwrapped.idle_action if hasattr(env.unwrapped, "idle_action") else 1)
    if render:
        env.render()
    env.close()


def _vector(observation: str) -> None:
    import gymnasium as gym

    for env_id in ("FogDriveRL-v0", "FogDriveRLHazard-v0"):
        envs = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", observation=observation,
                            fog="dense")  # fmt: skip
        envs.reset(seed=0)
        for _ in range(2):
            envs.step(envs.action_space.sample())
        envs.close()


FOG_LEVELS = ["light", "moderate", "dense"]

#: Path name → a function that runs it (at the sizes the path's envs use).
PATHS: dict[str, Callable[[], None]] = {
    "fogdrive": lambda: _episode("FogDrive-v0", render=True, fog=FOG_LEVELS),
    "fogdrive-night": lambda: _episode("FogDrive-v0", render=True, fog=FOG_LEVELS, time_of_day="night"),
    "rl-pixels": lambda: [_episode(i, fog="dense") for i in ("FogDriveRL-v0", "FogDriveRLHazard-v0")],
    "rl-objects": lambda: [_episode(i, fog="dense", observation="objects") for i in ("FogDriveRL-v0", "FogDriveRLHazard-v0")],
    "vector": lambda: [_vector(o) for o in ("pixels", "objects")],
}  # fmt: skip


def entries(*paths: str) -> list[KernelEntry]:
    """The kernels of ``paths`` (each kernel once, with the union of its signatures)."""
    merged: dict[tuple[str, str], KernelEntry] = {}
    for path in paths:
        if path not in TABLE:
            raise ValueError(f"path must be one of {sorted(TABLE)}, got {path!r}")
        for module, name, sigs, seconds in TABLE[path]:
            old = merged.get((module, name))
            if old is None:
                merged[module, name] = KernelEntry(module, name, tuple(tuple(s) for s in sigs), seconds)
            else:
                new = tuple(dict.fromkeys(old.signatures + tuple(tuple(s) for s in sigs)))
                merged[module, name] = old._replace(signatures=new, seconds=max(old.seconds, seconds))
    return list(merged.values())


_done: set[str] = set()


def ensure_compiled(*paths: str) -> None:
    """Compile the kernels of ``paths`` that the cache lacks, in parallel processes (once per process and path)."""
    todo = [p for p in paths if p not in _done]
    if not todo:
        return
    compile_kernels(entries(*todo))
    _done.update(todo)


def path_of(config) -> list[str]:
    """The paths whose kernels a :class:`~fog_gym.envs.config.FogDriveConfig` env calls: the RL presets' sizes
    (``rl-pixels``) below the serial kernels' threshold, the full rig's above it, by day or by night."""
    from fog_gym._numba import SERIAL_BELOW

    pixels = sum(c.width * c.height for c in config.rig.cameras)
    night = config.time_of_day == "night"
    if pixels >= SERIAL_BELOW:
        return ["fogdrive-night"] if night else ["fogdrive"]
    return ["rl-pixels", "fogdrive-night"] if night else ["rl-pixels"]


class _Recorder:
    """Records the fog-gym kernels compiled from Python (not those compiled inside another kernel) with their
    argument types and seconds."""

    def __init__(self) -> None:
        from numba.core import event

        class Listener(event.Listener):
            def on_start(inner, ev):  # noqa: N805
                self.depth += 1
                if self.depth == 1:
                    self.start = time.perf_counter()

            def on_end(inner, ev):  # noqa: N805
                if self.depth == 1:
                    f = ev.data["dispatcher"].py_func
                    if f.__module__.startswith("fog_gym"):
                        key = (f.__module__, f.__name__)
                        sig = [repr(t) for t in ev.data["args"]]
                        sigs, secs = self.found.get(key, ([], 0.0))
                        self.found[key] = (sigs + [sig], secs + time.perf_counter() - self.start)
                self.depth -= 1

        self.depth = 0
        self.start = 0.0
        self.found: dict[tuple[str, str], tuple[list, float]] = {}
        event.register("numba:compile", Listener())

    def rows(self) -> list:
        return [[m, n, sigs, round(secs, 1)] for (m, n), (sigs, secs) in sorted(self.found.items())]


def record(path: str) -> list:
    """Run ``path`` in this process and return the kernels it compiled (run it on an empty numba cache:
    ``NUMBA_CACHE_DIR``), as :mod:`fog_gym.envs.kernel_table` lists them."""
    rec = _Recorder()
    PATHS[path]()
    return rec.rows()


class _Calls:
    """Records the fog-gym kernels called from Python with their argument types, whether a call compiles them or loads
    them from the cache (numba resolves a Python call's first types in ``_compile_for_args``; a kernel called inside
    another kernel never passes there, as the table wants)."""

    def __enter__(self) -> _Calls:
        from numba.core.dispatcher import _DispatcherBase

        self.found: dict[tuple[str, str], list] = {}
        self._base, self._orig = _DispatcherBase, _DispatcherBase._compile_for_args
        found, orig = self.found, self._orig

        def compile_for_args(disp, *args, **kws):
            f = disp.py_func
            if f.__module__.startswith("fog_gym"):
                sig = [repr(disp.typeof_pyval(a)) for a in args]
                sigs = found.setdefault((f.__module__, f.__name__), [])
                if sig not in sigs:
                    sigs.append(sig)
            return orig(disp, *args, **kws)

        _DispatcherBase._compile_for_args = compile_for_args
        return self

    def __exit__(self, *exc) -> None:
        self._base._compile_for_args = self._orig


def check(path: str) -> list:
    """The kernels (and argument types) ``path`` calls from Python that its table row lacks (empty when the table is
    complete), on a warm cache or a cold one alike. Runs the path in this process, so run it in a fresh one
    (``python -m fog_gym.envs.warmup --check`` runs each path in its own)."""
    ensure_compiled(path)
    known = {(e.module, e.name): set(e.signatures) for e in entries(path)}
    with _Calls() as calls:
        PATHS[path]()
    out = []
    for (module, name), sigs in sorted(calls.found.items()):
        missing = [s for s in sigs if tuple(s) not in known.get((module, name), set())]
        if missing:
            out.append([module, name, missing, 0.0])
    return out


def main(argv: list[str] | None = None) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="python -m fog_gym.envs.warmup", description="Compile the kernels of env paths "
                                "ahead (in parallel processes), or record the kernels a path compiles (--record).")  # fmt: skip
    p.add_argument("paths", nargs="*", choices=[*PATHS, []], default=[], help=f"paths (default all: {', '.join(PATHS)})")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--record", action="store_true", help="run the path here and print its kernels as JSON "
                      "(use an empty NUMBA_CACHE_DIR and FOG_GYM_COMPILE=lazy)")  # fmt: skip
    mode.add_argument("--check", action="store_true", help="compile the paths ahead, run them, and print as JSON the "
                      "kernels each still compiled (what the table misses)")  # fmt: skip
    a = p.parse_args(argv)
    paths = a.paths or list(PATHS)
    if a.check:
        if len(paths) == 1:
            print(json.dumps({paths[0]: check(paths[0])}))
            return 0
        # each path in a fresh process: a kernel an earlier path already resolved would hide from a later one
        out = {}
        for path in paths:
            run = subprocess.run([sys.executable, "-m", "fog_gym.envs.warmup", "--check", path], capture_output=True,
                                 text=True, check=False)  # fmt: skip
            if run.returncode:
                sys.stderr.write(run.stderr)
                return run.returncode
            out.update(json.loads(run.stdout.strip().splitlines()[-1]))
        print(json.dumps(out))
        return 0
    if a.record:
        if len(paths) != 1:
            p.error("--record takes one path")
        os.environ["FOG_GYM_COMPILE"] = "lazy"
        print(json.dumps(record(paths[0])))
        return 0
    ensure_compiled(*paths)
    return 0


if __name__ == "__main__":
    sys.exit(main())
