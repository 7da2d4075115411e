"""Worlds as coroutines, their kernels in rounds (fog_gym._rounds): order, identity, errors, locks, threads."""

from __future__ import annotations

import gc
import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from fog_gym import _rounds
from fog_gym._numba import defer, pick
from fog_gym._rounds import Crew, deferring, held, run_rounds
from fog_gym.sensors import raycast


@njit(nogil=True)
def _scaled(x, k):
    return x * k


@pytest.fixture
def crew():
    c = Crew(2)
    yield c
    c.close()


@given(st.lists(st.integers(0, 4), min_size=1, max_size=6))
@settings(max_examples=20, deadline=None)
def test_each_world_gets_its_own_kernels_results_in_rounds_as_many_as_the_longest_step(calls):
    crew = Crew(2)
    try:
        def step(i, n):
            x = np.full(3, float(i))
            for k in range(n):
                x = defer(_scaled)(x, 2.0)  # the next kernel's argument is the last one's result
            return i, x

        out = run_rounds([lambda i=i, n=n: step(i, n) for i, n in enumerate(calls)], crew)
        assert [o[0] for o in out] == list(range(len(calls)))
        for (i, x), n in zip(out, calls):
            np.testing.assert_array_equal(x, np.full(3, i * 2.0**n))
        assert crew.rounds == max(calls)
    finally:
        crew.close()


def test_a_rounds_kernels_run_on_every_thread_of_the_crew(crew):
    both = threading.Barrier(2, timeout=10)  # passes only when two kernels of the round run at the same time
    seen = set()

    def kernel(i):
        seen.add(threading.get_ident())
        both.wait()
        return i

    assert run_rounds([lambda i=i: _rounds.deferred(kernel)(i) for i in range(2)], crew) == [0, 1]
    assert len(seen) == 2 and threading.get_ident() in seen


def test_a_picked_twin_waits_for_the_round_and_gives_the_bits_of_a_direct_call(crew):
    rng = np.random.default_rng(0)
    prims = {"centers": rng.uniform(-20, 20, (30, 3)), "halves": rng.uniform(0.5, 2, (30, 3)),
             "yaws": rng.uniform(-3, 3, 30)}  # fmt: skip
    dirs = rng.normal(size=(500, 3))
    alone = [raycast.cast_rays(np.array([0.0, 0, 1 + i]), dirs, 60.0, prims) for i in range(3)]
    inside = []

    def step(i):
        inside.append(deferring())
        return raycast.cast_rays(np.array([0.0, 0, 1 + i]), dirs, 60.0, prims)

    together = run_rounds([lambda i=i: step(i) for i in range(3)], crew)
    assert inside == [True] * 3 and not deferring() and crew.rounds == 1
    for a, b in zip(alone, together):
        for x, y in zip(a, b):
            assert x.tobytes() == y.tobytes()
    twin = njit(lambda x: x)
    assert pick(None, twin, 0) is twin  # outside a world's step: the twin itself


def test_a_kernels_error_is_raised_where_the_world_called_it(crew):
    def kernel(x):
        if x < 0:
            raise ValueError("negative")
        return x

    def step(i):
        try:
            return _rounds.deferred(kernel)(i - 1)
        except ValueError as e:
            return str(e)

    assert run_rounds([lambda i=i: step(i) for i in range(3)], crew) == ["negative", 0, 1]


def test_a_world_that_fails_lets_the_others_finish_then_its_error_is_raised(crew):
    finished = []

    def step(i):
        _rounds.deferred(lambda: None)()
        if i == 1:
            raise KeyError("world 1")
        _rounds.deferred(lambda: None)()
        finished.append(i)

    with pytest.raises(KeyError, match="world 1"):
        run_rounds([lambda i=i: step(i) for i in range(4)], crew)
    assert finished == [0, 2, 3]


def test_a_world_holding_a_shared_lock_runs_its_kernels_in_place(crew):
    lock = threading.Lock()
    flags = []

    def step(i):
        with held(lock):
            flags.append(deferring())
            x = defer(_scaled)(np.ones(2), float(i))  # in place: the next world would wait for the lock forever
        flags.append(deferring())
        return defer(_scaled)(x, 2.0)[0]

    assert run_rounds([lambda i=i: step(i) for i in range(3)], crew) == [0.0, 2.0, 4.0]
    assert flags == [False, True] * 3 and crew.rounds == 1


@given(st.one_of(st.integers(max_value=0), st.floats(), st.just(True), st.text(max_size=3)))
@settings(max_examples=20, deadline=None)
def test_bad_thread_counts_fail_before_any_thread_starts(threads):
    before = threading.active_count()
    with pytest.raises(ValueError, match="threads must be an integer >= 1"):
        Crew(threads)
    assert threading.active_count() == before


def test_a_closed_crew_stops_its_helpers_and_runs_no_more_rounds():
    crew = Crew(3)
    helpers = list(crew._helpers)
    assert all(t.is_alive() for t in helpers)
    crew.close()
    crew.close()  # twice: harmless
    assert not any(t.is_alive() for t in helpers)
    with pytest.raises(RuntimeError, match="closed"):
        crew.run([])


def test_a_crew_dropped_without_closing_stops_its_helpers():
    crew = Crew(2)
    helpers = list(crew._helpers)
    del crew
    gc.collect()
    for t in helpers:
        t.join(timeout=10)
    assert not any(t.is_alive() for t in helpers)


def test_the_spin_sees_a_flag_reached_and_gives_up_after_its_reads():
    flags = np.zeros(16, np.int64)
    flags[8] = 3
    assert _rounds._spin_until(flags, 8, 3, 1) and _rounds._spin_until(flags, 8, 2, 1)
    assert not _rounds._spin_until(flags, 8, 4, 1000) and not _rounds._spin_until(flags, 0, 1, 10)


def test_helpers_asleep_after_their_spin_wake_for_the_next_round(crew):
    import time

    both = threading.Barrier(2, timeout=10)

    def kernel(i):
        both.wait()  # both threads in the round at once
        return i

    for _ in range(3):
        time.sleep(5 * _rounds.SPIN_SECONDS)  # longer than the helpers stay awake
        assert run_rounds([lambda i=i: _rounds.deferred(kernel)(i) for i in range(2)], crew) == [0, 1]


def test_a_worlds_step_sees_the_callers_context_variables(crew):
    from fog_gym.checks import command_line, option

    def step():
        _rounds.deferred(lambda: None)()
        return option("save", "'F'", "F")

    with command_line():  # the fog-gym command's handlers: errors name its flags
        assert run_rounds([step, step], crew) == ["--save F", "--save F"]
    assert run_rounds([step], crew) == ["save='F'"]
