"""Helpers shared by test modules."""

import contextlib
import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def load_module(relative: str):
    """Import an example of the repository by path (``"examples/bc_minari.py"``) as a module (code of the package is
    imported from the package, never by path)."""
    path = ROOT / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class Killed(Exception):
    """Raised by :func:`killed_after_first_epoch` in place of a kill -9."""


@contextlib.contextmanager
def killed_after_first_epoch(monkeypatch):
    """Within the block, a training unit dies (:class:`Killed`) right after its first epoch's checkpoint is saved."""
    from fog_gym.experiments.runner import EpochCheckpoint

    save = EpochCheckpoint.save

    def save_then_die(self, state):
        save(self, state)
        if state["epoch"] == 1:
            raise Killed

    monkeypatch.setattr(EpochCheckpoint, "save", save_then_die)
    try:
        yield
    finally:
        monkeypatch.setattr(EpochCheckpoint, "save", save)
