"""Helpers shared by test modules."""

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
