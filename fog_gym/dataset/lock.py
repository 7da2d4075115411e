"""One writer per dataset root: an exclusive advisory lock that ``generate``, ``RecordFogDrive`` and ``export`` hold
on their output root while they write.

The lock is ``fcntl.flock`` on ``<root>/.fog-gym.lock``, which names its holder (pid, host, start time, command) as
JSON. The kernel drops a ``flock`` when its process ends, however it ends, so a writer killed with ``kill -9`` leaves
the file but not the lock: the next writer takes it, says it took over a stale lock, and goes on (``--resume``
completes the set). A second writer while the first runs gets :class:`DatasetLocked`, whose one line names the root
and the holder. Ray generation holds the lock in the driver, which alone decides what is written where.

``flock`` is local to a host (and on NFS only as good as its lock daemon); the lock guards writers on one machine or
one well-behaved shared file system. The library ``filelock`` was not used: it truncates the lock file on opening,
which would erase the holder's record that the refusal names.

Example:
    >>> import tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> with DatasetLock(root, "generate") as lock:
    ...     try:
    ...         DatasetLock(root, "export").acquire()
    ...     except DatasetLocked as e:
    ...         print(str(e).split(" is being written")[0] == f"dataset root {root}")
    True
    >>> (root / LOCK_FILE).exists()  # released: the record is gone
    False
"""

from __future__ import annotations

import datetime as _dt
import errno
import fcntl
import json
import os
import socket
import sys
from pathlib import Path
from typing import Any

LOCK_FILE = ".fog-gym.lock"


class DatasetLocked(RuntimeError):
    """Another writer holds the dataset root; ``str()`` is one line naming the root and the holder."""

    def __init__(self, root: Path, holder: dict[str, Any]) -> None:
        self.root, self.holder = root, holder
        super().__init__(f"dataset root {root} is being written by {describe(holder)}; wait for it to finish or "
                         "stop it (one writer per dataset)")  # fmt: skip


class DatasetLockError(OSError):
    """The root cannot be locked for writing (read-only, no permission, not a folder); ``str()`` is one line."""

    def __str__(self) -> str:
        return str(self.strerror)


def describe(holder: dict[str, Any]) -> str:
    """``pid P on host H since T (command C)`` for a holder record (``an unknown writer`` for an unreadable one).

    >>> describe({"pid": 7, "host": "n1", "started": "2026-11-26T10:00:00+00:00", "command": "generate"})
    'pid 7 on host n1 since 2026-11-26T10:00:00+00:00 (generate)'
    """
    if not holder.get("pid"):
        return "an unknown writer"
    return f"pid {holder['pid']} on host {holder.get('host', '?')} since {holder.get('started', '?')} ({holder.get('command', '?')})"


def read_holder(root: str | Path) -> dict[str, Any] | None:
    """The record of the lock file of ``root`` (None when there is none; ``{}`` when it cannot be read)."""
    try:
        text = (Path(root) / LOCK_FILE).read_text()
    except FileNotFoundError:
        return None
    except OSError:
        return {}
    try:
        record = json.loads(text) if text.strip() else {}
    except json.JSONDecodeError:
        return {}
    return record if isinstance(record, dict) else {}


class DatasetLock:
    """The exclusive lock of one dataset root, as a context manager (or :meth:`acquire` / :meth:`release`).

    ``acquire`` creates the root if needed and raises :class:`DatasetLocked` while another process holds it, or
    :class:`DatasetLockError` when the root cannot be written. ``stale`` is the record of a holder that ended
    without releasing (killed), which this lock took over; ``quiet`` keeps the take-over notice off stderr.
    """

    def __init__(self, root: str | Path, command: str, quiet: bool = False) -> None:
        self.root = Path(root)
        self.command = command
        self.quiet = quiet
        self.stale: dict[str, Any] | None = None
        self._fd: int | None = None

    @property
    def path(self) -> Path:
        return self.root / LOCK_FILE

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self) -> DatasetLock:
        if self._fd is not None:
            return self
        if self.root.exists() and not self.root.is_dir():
            raise DatasetLockError(errno.ENOTDIR, f"dataset root {self.root} exists and is not a folder")
        while True:
            try:
                self.root.mkdir(parents=True, exist_ok=True)
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                raise DatasetLockError(e.errno, f"cannot lock dataset root {self.root} for writing: "
                                                f"{e.strerror or e}") from None  # fmt: skip
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise DatasetLocked(self.root, read_holder(self.root) or {}) from None
            except OSError as e:
                os.close(fd)
                raise DatasetLockError(e.errno, f"cannot lock dataset root {self.root}: {e.strerror or e}") from None
            # the file may have been released and removed between our open and our flock: lock the one on disk
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        previous = os.read(fd, 1 << 16)
        if previous.strip():
            try:
                self.stale = json.loads(previous)
            except json.JSONDecodeError:
                self.stale = {}
            if not self.quiet:
                print(f"fog-gym: took over the stale lock of {self.root} left by {describe(self.stale or {})}, "
                      "which no longer runs", file=sys.stderr)  # fmt: skip
        record = {"pid": os.getpid(), "host": socket.gethostname(), "command": self.command,
                  "started": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}  # fmt: skip
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps(record).encode() + b"\n", 0)
            os.fsync(fd)
        except OSError as e:
            os.close(fd)
            raise DatasetLockError(e.errno, f"cannot lock dataset root {self.root} for writing: {e.strerror or e}") from None
        self._fd = fd
        return self

    def release(self) -> None:
        """Remove the record and drop the lock (idempotent)."""
        if self._fd is None:
            return
        try:
            self.path.unlink()
        except OSError:
            pass
        os.close(self._fd)
        self._fd = None

    def __enter__(self) -> DatasetLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()

    def __del__(self) -> None:
        if getattr(self, "_fd", None) is not None:
            try:
                os.close(self._fd)
            except OSError:
                pass
