"""The documentation: every Python block of README.md and of every docs page runs as a reader would run it, the
README stays a front door whose links resolve, and the docs site builds with ``mkdocs build --strict``.

Each file's blocks run in order, in one namespace per file and a temporary working folder per file: ````python````
blocks are executed; ````pycon```` blocks (``>>>`` prompts with outputs) run as doctests, so the outputs a page shows
are checked. A block preceded by ``<!-- readme-test: slow -->`` is marked slow (run with ``-m slow``); one preceded
by ``<!-- readme-test: needs MODULE -->`` is skipped where MODULE (an optional extra) is not installed.
"""

from __future__ import annotations

import doctest
import os
import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
#: README.md first, then every page of the docs site.
PAGES = [README, *sorted((ROOT / "docs").rglob("*.md"))]
_BLOCK = re.compile(r"(?:<!-- readme-test: (?P<marks>[^>]*?) -->\s*\n)?```(?P<lang>python|pycon)\n(?P<code>.*?)```", re.S)
_LINK = re.compile(r"\]\((?!https?://|#|mailto:)(?P<target>[^)\s#]+)(?:#[^)]*)?\)")


def doc_blocks(text: str) -> list[tuple[int, str, str, str]]:
    """(line, language, code, marks) of every Python block in ``text``.

    >>> doc_blocks("x\\n<!-- readme-test: slow -->\\n```python\\na = 1\\n```\\n")
    [(3, 'python', 'a = 1\\n', 'slow')]
    """
    return [(text[: m.start("lang")].count("\n") + 1, m["lang"], m["code"], m["marks"] or "") for m in _BLOCK.finditer(text)]


def _params():
    out = []
    for page in PAGES:
        rel = page.relative_to(ROOT).as_posix()
        for line, lang, code, marks in doc_blocks(page.read_text()):
            m = [pytest.mark.slow] if "slow" in marks.split() else []
            need = re.search(r"needs (\S+)", marks)
            if need and importlib.util.find_spec(need.group(1)) is None:
                m.append(pytest.mark.skip(reason=f"needs the optional {need.group(1)}"))
            out.append(pytest.param(rel, lang, code, id=f"{rel}:{line}", marks=m))
    return out


@pytest.fixture(scope="module")
def namespaces(tmp_path_factory):
    """page → (its namespace, its working folder), made on the page's first block."""
    spaces: dict[str, tuple[dict, Path]] = {}

    def get(page: str) -> tuple[dict, Path]:
        if page not in spaces:
            folder = tmp_path_factory.mktemp(re.sub(r"\W+", "_", page))
            spaces[page] = ({"__name__": "__docs__"}, folder)
        return spaces[page]

    yield get
    for ns, _ in spaces.values():
        for value in list(ns.values()):
            if isinstance(value, gym.Env):  # environments the page made
                value.close()


@pytest.mark.parametrize("page, lang, code", _params())
def test_doc_block_runs(namespaces, monkeypatch, page, lang, code):
    ns, folder = namespaces(page)
    monkeypatch.chdir(folder)
    if lang == "python":
        exec(compile(code, str(ROOT / page), "exec"), ns)
        return
    failures: list[str] = []
    test = doctest.DocTestParser().get_doctest(code, ns, page, str(ROOT / page), 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test, out=failures.append, clear_globs=False)
    assert not failures, "".join(failures)
    ns.update(test.globs)


def test_readme_is_a_front_door():
    assert len(README.read_text().splitlines()) <= 250


def test_readme_links_resolve():
    """The README is read on its own (on a code host, in the package metadata): its relative links must exist."""
    missing = [m["target"] for m in _LINK.finditer(README.read_text()) if not (ROOT / m["target"]).exists()]
    assert missing == []


def test_docs_site_builds_strict(tmp_path):
    """``mkdocs build --strict`` fails on any warning: a broken link or anchor, a page left out of the nav, a
    missing image."""
    pytest.importorskip("mkdocs")
    pytest.importorskip("material")
    site = tmp_path / "site"
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
                           "--site-dir", str(site)], cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    built = {p.relative_to(site).as_posix() for p in site.rglob("index.html")}
    assert {_url(p.relative_to(ROOT / "docs")) for p in PAGES[1:]} <= built


def _url(page: Path) -> str:
    """Where MkDocs (directory URLs) writes a page: ``fog.md`` → ``fog/index.html``, ``index.md`` → ``index.html``.

    >>> _url(Path("experiments/index.md")), _url(Path("experiments/exp1.md"))
    ('experiments/index.html', 'experiments/exp1/index.html')
    """
    parts = page.with_suffix("").parts
    return "/".join([*(parts[:-1] if parts[-1] == "index" else parts), "index.html"])
