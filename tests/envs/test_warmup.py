"""Compiling ahead: every env path's kernels are in the compile table, cold kernels compile in worker processes
behind a progress bar that names them, a warm cache compiles nothing, and the table's type strings round-trip."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import typeof

from fog_gym._numba import KernelEntry, parse_signature
from fog_gym.envs.kernel_table import TABLE
from fog_gym.envs.warmup import PATHS, entries, path_of


def _run(code: str, cache: str | None = None, **env: str) -> subprocess.CompletedProcess:
    extra = {"NUMBA_CACHE_DIR": cache} if cache else {}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env={**os.environ, **extra, **env})  # fmt: skip


def test_every_path_compiles_nothing_its_table_row_misses():
    """Run every path after compiling its row ahead: no kernel compiles on its first call (scripts/kernel_table.py
    rewrites the table when this fails)."""
    out = subprocess.run([sys.executable, "-m", "fog_gym.envs.warmup", "--check"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    missed = {path: [f"{m}.{n} {sigs}" for m, n, sigs, _ in rows] for path, rows in json.loads(out.stdout).items()}
    assert missed == {path: [] for path in PATHS}



def test_the_check_sees_a_kernel_the_cache_already_holds():
    """A kernel loaded from a warm cache compiles nothing, so a check that listened for compilations missed kernels
    the table lacks whenever an earlier test had cached them; the check records calls from Python instead."""
    code = "import numpy as np; from fog_gym.geometry import polygon_area; polygon_area(np.zeros((3, 2)), 3)"
    first = _run(code)
    assert first.returncode == 0, first.stderr
    # a fresh process on the now warm cache: the kernel loads from the cache, and the check still sees its call
    code_warm = ("import numpy as np; from fog_gym.geometry import polygon_area; from fog_gym.envs.warmup import _Calls\n"
                 "with _Calls() as c: polygon_area(np.zeros((4, 2)), 4)\n"
                 "print(sorted(c.found.items()))")  # fmt: skip
    out = _run(code_warm)
    assert out.returncode == 0 and "compiling" not in out.stderr, out.stderr
    assert out.stdout.strip() == str([(("fog_gym.geometry", "polygon_area"),
                                       [["Array(float64, 2, 'C', False, aligned=True)", "int64"]])])


def test_the_table_names_every_path_and_only_kernels_that_exist():
    assert list(TABLE) == list(PATHS)
    for e in entries(*PATHS):
        assert e.signatures and e.seconds >= 0
        import importlib

        kernel = getattr(importlib.import_module(e.module), e.name)
        assert hasattr(kernel, "compile"), e.label  # a numba dispatcher
        for sig in e.signatures:
            assert len(parse_signature(sig)) == len(sig)


SMALL = [KernelEntry("fog_gym.geometry", "polygon_area", (("Array(float64, 2, 'C', False, aligned=True)", "int64"),), 1.0),
         KernelEntry("fog_gym.render.surface", "surface_cell", (("float64", "float64", "Array(uint8, 1, 'C', False, aligned=True)",
                     "int64", "int64", "int64"),), 0.5)]  # fmt: skip


def test_cold_kernels_compile_in_two_processes_behind_a_bar_that_names_them_then_nothing(tmp_path):
    code = ("import sys; from fog_gym._numba import KernelEntry, compile_kernels; "
            f"e = [KernelEntry(*x) for x in {[tuple(e) for e in SMALL]!r}]; "
            "done = compile_kernels(e, jobs=2); again = compile_kernels(e, jobs=2); "
            "print([d.label for d in done], again)")  # fmt: skip
    out = _run(code, str(tmp_path))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "['geometry.polygon_area', 'render.surface.surface_cell'] []"
    bar = out.stderr
    assert "compiling kernels (first run only, 2 processes)" in bar and "2/2" in bar and "done in" in bar
    assert "geometry.polygon_area" in bar  # the longest first, named while it compiles
    # the caller loads both from the cache: calling them compiles nothing more
    code = ("import numpy as np; from fog_gym.geometry import polygon_area; "
            "print(polygon_area(np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]]), 4))")  # fmt: skip
    out = _run(code, str(tmp_path))
    assert out.stdout.strip() == "1.0" and "compiling" not in out.stderr


def test_lazy_mode_compiles_on_first_call_and_names_the_kernel(tmp_path):
    code = ("from fog_gym._numba import KernelEntry, compile_kernels; "
            f"print(compile_kernels([KernelEntry(*{tuple(SMALL[0])!r})])); "
            "import numpy as np; from fog_gym.geometry import polygon_area; polygon_area(np.zeros((3, 2)), 3)")  # fmt: skip
    out = _run(code, str(tmp_path), FOG_GYM_COMPILE="lazy")
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"
    assert out.stderr.strip() == "fog-gym: compiling geometry.polygon_area …"


def test_a_path_outside_the_table_is_refused():
    with pytest.raises(ValueError, match="path must be one of"):
        entries("fogdrive", "racing")


def test_env_sizes_pick_their_paths():
    from dataclasses import replace

    from fog_gym.envs.config import FogDriveConfig

    full = FogDriveConfig()
    small = replace(full, rig=full.rig.with_resolution((32, 32)))  # 4 × 32 × 32 pixels: the serial kernels
    assert path_of(full) == ["fogdrive"] and path_of(replace(full, time_of_day="night")) == ["fogdrive-night"]
    assert path_of(small) == ["rl-pixels"]
    assert path_of(replace(small, time_of_day="night")) == ["rl-pixels", "fogdrive-night"]


_DTYPES = st.sampled_from([np.uint8, np.uint16, np.int32, np.int64, np.float32, np.float64, np.bool_])


@settings(max_examples=40, deadline=None)
@given(_DTYPES, st.integers(1, 4), st.booleans(), st.booleans())
def test_array_types_round_trip_through_their_repr(dtype, ndim, readonly, fortran):
    a = np.zeros((2,) * ndim, dtype, order="F" if fortran else "C")
    a.flags.writeable = not readonly
    t = typeof(a)
    assert parse_signature((repr(t),)) == (t,)


@pytest.mark.parametrize("value", [1.5, 3, True, np.uint64(7), np.float32(2.0)])
def test_scalar_types_round_trip_through_their_repr(value):
    t = typeof(value)
    assert parse_signature((repr(t),)) == (t,)
