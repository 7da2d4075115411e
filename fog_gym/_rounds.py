"""Many worlds' steps in one Python thread, their kernels in rounds on every core.

Each world of the pixel vector env runs a step of Python that calls kernels (the ray cast, the camera's set-up and
raster, the fogs, the bird's-eye image). :func:`run_rounds` runs each world's step as a coroutine (a ``greenlet``)
in the calling thread. A kernel that a world calls through :func:`fog_gym._numba.pick` (its serial twin) or
:func:`fog_gym._numba.defer` is not run there but handed back; once every world has reached its next kernel (or its
end), the round's kernels run together on a :class:`Crew` — the calling thread and ``threads - 1`` helpers, each
taking the next kernel until none is left — and each world resumes with its kernel's result (or its error, raised
where the kernel was called). So the worlds' Python runs in one thread, never waiting for the GIL, and the kernels,
which release it, run in parallel with nothing else to wait for: a step costs the Python of all worlds plus their
kernels shared among the threads.

A world's kernels receive the arguments they receive when the world runs alone, and nothing a world writes is shared
with another (what a thread kept for itself, a world keeps for itself: :func:`deferring`), so the results are the
same bits. A world that holds a lock the worlds share runs its kernels in place (:func:`held`).

Example:
    >>> from numba import njit
    >>> from fog_gym._numba import defer
    >>> double = njit(lambda x: 2 * x)
    >>> def step(i):
    ...     return defer(double)(i) + 1  # the kernel runs in the round, with every world's
    >>> crew = Crew(2)
    >>> run_rounds([lambda i=i: step(i) for i in range(3)], crew), crew.rounds
    ([1, 3, 5], 1)
    >>> crew.close()
"""

from __future__ import annotations

import contextvars
import itertools
import threading
import time
import weakref
from contextlib import contextmanager
from typing import Any, Callable, Iterator, NamedTuple, Sequence

import numpy as np
from greenlet import getcurrent, greenlet
from numba import njit, types
from numba.core import cgutils
from numba.core.extending import intrinsic


class _Call(NamedTuple):
    kernel: Any
    args: tuple


class _Done(NamedTuple):
    value: Any


class _Failed(NamedTuple):
    error: BaseException


class _World(greenlet):
    """A world's step, run as a coroutine by :func:`run_rounds` (its picked kernels wait for the round)."""

    inline = 0  # > 0 while it holds a lock the worlds share (:func:`held`): its kernels then run in place


def deferring() -> bool:
    """Whether the caller is a world's step inside :func:`run_rounds` (its kernels go to the round); such a step must
    not keep state for its thread (the worlds take turns in one thread).

    >>> deferring()
    False
    """
    g = getcurrent()
    return type(g) is _World and not g.inline


@contextmanager
def held(lock: Any) -> Iterator[None]:
    """``with lock`` for a lock that worlds share: a world's step that holds it runs its kernels in place (were it to
    wait for the round, the next world would wait for the lock in the same thread, forever)."""
    g = getcurrent()
    world = type(g) is _World
    if world:
        g.inline += 1
    try:
        with lock:
            yield
    finally:
        if world:
            g.inline -= 1


def deferred(kernel: Any) -> Callable:
    """``kernel``, to call from a world's step: the call waits for the round and returns the kernel's result."""

    def call(*args: Any) -> Any:
        out = getcurrent().parent.switch(_Call(kernel, args))
        if isinstance(out, _Failed):
            raise out.error
        return out

    return call


def _body(f: Callable[[], Any]) -> Callable[[], _Done]:
    return lambda: _Done(f())


def run_rounds(steps: Sequence[Callable[[], Any]], crew: Crew) -> list:
    """Each of ``steps`` (callables without arguments) run to its end, their kernels in rounds on ``crew``; their
    results in order. Should a step raise, the others still run to their end, then the first error is raised."""
    worlds = [_World(_body(f)) for f in steps]
    context = contextvars.copy_context()
    for w in worlds:  # the caller's context variables, as a thread's call would see them
        w.gr_context = context.copy()
    results: list = [None] * len(worlds)
    errors: list[BaseException] = []
    waiting: list[tuple[int, _Call]] = []

    def advance(i: int, *value: Any) -> None:
        try:
            out = worlds[i].switch(*value)
        except BaseException as e:  # noqa: BLE001 - raised below, once every world has finished
            errors.append(e)
            return
        if isinstance(out, _Done):
            results[i] = out.value
        else:
            waiting.append((i, out))

    for i in range(len(worlds)):
        advance(i)
    while waiting:
        turn = list(waiting)
        waiting.clear()
        for (i, _), out in zip(turn, crew.run([call for _, call in turn])):
            advance(i, out)
    if errors:
        raise errors[0]
    return results


@intrinsic
def _load_acquire(typingctx, flags, i):
    """``flags[i]`` read from memory on every call (an atomic load: a spinning loop sees another thread's store)."""

    def codegen(context, builder, sig, args):
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, sig.args[0], ary, [args[1]])
        return builder.load_atomic(ptr, "acquire", 8)

    return types.int64(flags, types.intp), codegen


@njit(cache=True, nogil=True)
def _spin_until(flags, i, target, spins):
    """Whether ``flags[i]`` reached ``target`` within ``spins`` reads (without the GIL: a thread waiting so stays
    awake, where one asleep on this project's virtual machines took 50–300 µs to wake)."""
    for _ in range(spins):
        if _load_acquire(flags, i) >= target:
            return True
    return False


#: How long a crew's threads wait awake for the next round (or the caller for its helpers) before they sleep.
SPIN_SECONDS = 0.002
_SPINS: list[int] = []


def _spins() -> int:
    """Reads of :func:`_spin_until` in :data:`SPIN_SECONDS` (measured once)."""
    if not _SPINS:
        flags = np.zeros(1, np.int64)
        _spin_until(flags, 0, 1, 10)
        t = time.perf_counter()
        _spin_until(flags, 0, 1, 200_000)
        _SPINS.append(max(1000, int(SPIN_SECONDS * 200_000 / max(time.perf_counter() - t, 1e-9))))
    return _SPINS[0]


_LINE = 8  # int64s a cache line: each thread's flag on its own


class _Shared:
    """What a crew's threads share (its helpers hold this, not the crew, so an unclosed crew is still collected).
    ``flags[0]``: the rounds started; ``flags[_LINE * (h + 1)]``: the rounds helper ``h`` finished."""

    def __init__(self, helpers: int) -> None:
        self.flags = np.zeros(_LINE * (helpers + 1), np.int64)
        self.cond = threading.Condition()
        self.spins = _spins()
        self.calls: list[_Call] = []
        self.outs: list = []
        self.claim: Any = iter(())
        self.closed = False

    def work(self) -> None:
        calls, outs, claim = self.calls, self.outs, self.claim
        n = len(calls)
        while (k := next(claim)) < n:
            kernel, args = calls[k]
            try:
                outs[k] = kernel(*args)
            except BaseException as e:  # noqa: BLE001 - handed back to the world that called it
                outs[k] = _Failed(e)

    def start(self) -> None:
        """A round begins (the caller's side)."""
        self.flags[0] += 1
        with self.cond:
            self.cond.notify_all()

    def finish(self) -> None:
        """The caller waits for every helper to finish the round."""
        flags, r = self.flags, self.flags[0]
        for h in range(1, len(flags) // _LINE):
            if not _spin_until(flags, _LINE * h, r, self.spins):
                with self.cond:
                    self.cond.wait_for(lambda: flags[_LINE * h] >= r)

    def helper(self, h: int, init: Callable[[], Any] | None) -> None:
        if init is not None:
            init()
        flags, seen = self.flags, 0
        while True:
            if not _spin_until(flags, 0, seen + 1, self.spins):
                with self.cond:
                    self.cond.wait_for(lambda: flags[0] > seen)
            seen += 1
            if self.closed:
                return
            self.work()
            flags[_LINE * (h + 1)] = seen
            with self.cond:
                self.cond.notify_all()


def _stop(shared: _Shared, helpers: list[threading.Thread]) -> None:
    if helpers and not shared.closed:
        shared.closed = True
        shared.start()
        for t in helpers:
            t.join()


class Crew:
    """The threads that run a round's kernels: the caller's own and ``threads - 1`` helpers (each runs ``init`` first:
    :func:`fog_gym._numba.worker_crew` marks them as worker threads), each taking the next kernel until none is left.
    ``rounds`` counts the rounds run; :meth:`close` stops the helpers (also when the crew is collected).

    >>> Crew(0)
    Traceback (most recent call last):
    ...
    ValueError: threads must be an integer >= 1, got 0
    """

    def __init__(self, threads: int, init: Callable[[], Any] | None = None) -> None:
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ValueError(f"threads must be an integer >= 1, got {threads!r}")
        self.threads = threads
        self.rounds = 0
        self._shared = _Shared(threads - 1)
        self._helpers = [threading.Thread(target=self._shared.helper, args=(k, init), name=f"fog-gym-kernels-{k}",
                                          daemon=True) for k in range(threads - 1)]  # fmt: skip
        for t in self._helpers:
            t.start()
        self._finalizer = weakref.finalize(self, _stop, self._shared, self._helpers)

    def run(self, calls: list[_Call]) -> list:
        """Each call's result (or a ``_Failed`` holding its error), in order."""
        s = self._shared
        if s.closed:
            raise RuntimeError("this crew is closed")
        s.calls, s.outs, s.claim = calls, [None] * len(calls), itertools.count()
        self.rounds += 1
        if self._helpers and len(calls) > 1:
            s.start()
            s.work()
            s.finish()
        else:
            s.work()
        outs = s.outs
        s.calls, s.outs = [], []
        return outs

    def close(self) -> None:
        """Stop the helpers; a closed crew runs no more rounds. Closing twice is harmless."""
        self._finalizer()
        self._shared.closed = True
