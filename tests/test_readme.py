"""Every Python block of README.md runs, in order and in one namespace, as a reader would run them.

````python```` blocks are executed; ````pycon```` blocks (``>>>`` prompts with outputs) are run as doctests, so the
outputs the README shows are checked. A block preceded by ``<!-- readme-test: slow -->`` is marked slow (run with
``-m slow``); one preceded by ``<!-- readme-test: needs MODULE -->`` is skipped where MODULE (an optional extra)
is not installed. Blocks run in a temporary working folder.
"""

from __future__ import annotations

import doctest
import importlib.util
import os
import re
from pathlib import Path

import gymnasium as gym
import pytest

README = Path(__file__).resolve().parent.parent / "README.md"
_BLOCK = re.compile(r"(?:<!-- readme-test: (?P<marks>[^>]*?) -->\s*\n)?```(?P<lang>python|pycon)\n(?P<code>.*?)```", re.S)


def readme_blocks(text: str) -> list[tuple[int, str, str, str]]:
    """(line, language, code, marks) of every Python block in ``text``.

    >>> readme_blocks("x\\n<!-- readme-test: slow -->\\n```python\\na = 1\\n```\\n")
    [(3, 'python', 'a = 1\\n', 'slow')]
    """
    return [(text[: m.start("lang")].count("\n") + 1, m["lang"], m["code"], m["marks"] or "") for m in _BLOCK.finditer(text)]


def _params():
    out = []
    for line, lang, code, marks in readme_blocks(README.read_text()):
        m = [pytest.mark.slow] if "slow" in marks.split() else []
        need = re.search(r"needs (\S+)", marks)
        if need and importlib.util.find_spec(need.group(1)) is None:
            m.append(pytest.mark.skip(reason=f"needs the optional {need.group(1)}"))
        out.append(pytest.param(lang, code, id=f"README.md:{line}", marks=m))
    return out


@pytest.fixture(scope="module")
def namespace(tmp_path_factory):
    cwd = os.getcwd()
    os.chdir(tmp_path_factory.mktemp("readme"))
    ns: dict = {"__name__": "__readme__"}
    yield ns
    os.chdir(cwd)
    for value in list(ns.values()):
        if isinstance(value, gym.Env):  # environments the README made
            value.close()


@pytest.mark.parametrize("lang, code", _params())
def test_readme_block_runs(namespace, lang, code):
    if lang == "python":
        exec(compile(code, str(README), "exec"), namespace)
        return
    test = doctest.DocTestParser().get_doctest(code, namespace, "README", str(README), 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test, out=lambda s: failures.append(s), clear_globs=False)
    assert not failures, "".join(failures)
    namespace.update(test.globs)


failures: list[str] = []


@pytest.fixture(autouse=True)
def _clear_failures():
    failures.clear()
