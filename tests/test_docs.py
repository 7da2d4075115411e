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
        for index, (line, lang, code, marks) in enumerate(doc_blocks(page.read_text())):
            m = [pytest.mark.slow] if "slow" in marks.split() else []
            if not _runnable(marks):
                need = re.search(r"needs (\S+)", marks).group(1)
                m.append(pytest.mark.skip(reason=f"needs the optional {need}"))
            out.append(pytest.param(rel, index, lang, code, id=f"{rel}:{line}", marks=m))
    return out


def _runnable(marks: str) -> bool:
    need = re.search(r"needs (\S+)", marks)
    return not (need and importlib.util.find_spec(need.group(1)) is None)


def _run_block(ns: dict, page: str, lang: str, code: str) -> None:
    if lang == "python":
        exec(compile(code, str(ROOT / page), "exec"), ns)
        return
    failures: list[str] = []
    test = doctest.DocTestParser().get_doctest(code, ns, page, str(ROOT / page), 0)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    runner.run(test, out=failures.append, clear_globs=False)
    assert not failures, "".join(failures)
    ns.update(test.globs)


@pytest.fixture(scope="module")
def namespaces(tmp_path_factory):
    """page → (its namespace, its working folder, [how many of its blocks ran in it]), made on the page's first
    block in this process."""
    spaces: dict[str, tuple[dict, Path, list[int]]] = {}
    retired: list[tuple[dict, Path, list[int]]] = []

    def get(page: str, fresh: bool = False) -> tuple[dict, Path, list[int]]:
        if fresh and page in spaces:
            retired.append(spaces.pop(page))
        if page not in spaces:
            folder = tmp_path_factory.mktemp(re.sub(r"\W+", "_", page))
            spaces[page] = ({"__name__": "__docs__"}, folder, [0])
        return spaces[page]

    yield get
    for ns, _, _ in [*spaces.values(), *retired]:
        for value in list(ns.values()):
            if isinstance(value, gym.Env):  # environments the page made
                value.close()


@pytest.mark.parametrize("page, index, lang, code", _params())
def test_doc_block_runs(namespaces, monkeypatch, page, index, lang, code):
    """A block runs after the page's earlier blocks, in the page's namespace: where another test process ran some of
    them (pytest-xdist shares a page's blocks out), this one runs them first (all but slow ones and those whose
    optional module is missing, as a run in one process does); where a later block already ran here (the suite in
    another order, ``FOG_GYM_TEST_ORDER``), the page starts again in a fresh namespace and folder."""
    ns, folder, done = namespaces(page)
    if index < done[0]:
        ns, folder, done = namespaces(page, fresh=True)
    monkeypatch.chdir(folder)
    if done[0] < index:
        blocks = doc_blocks((ROOT / page).read_text())
        for _, earlier_lang, earlier_code, marks in blocks[done[0]:index]:
            if "slow" not in marks.split() and _runnable(marks):
                _run_block(ns, page, earlier_lang, earlier_code)
    _run_block(ns, page, lang, code)
    done[0] = max(done[0], index + 1)


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


def test_the_command_line_table_lists_every_subcommand_with_its_help():
    """``docs/installation.md`` lists the ``fog-gym`` subcommands in a table; the parser is the source of truth."""
    import argparse

    from fog_gym.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    text = (ROOT / "docs" / "installation.md").read_text()
    rows = re.findall(r"^\| `fog-gym ([\w-]+)` \|", text, re.M)
    assert sorted(rows) == sorted(sub.choices)


_CALL = re.compile(r"`(?P<name>fog_gym(?:\.\w+)+|\w+)(?:\((?P<args>[^`]*)\))?`", re.S)


def _public_function(dotted: str):
    """The fog-gym function a dotted name resolves to, or None (a module, class, constant, private name)."""
    import importlib
    import inspect
    import warnings

    warnings.simplefilter("ignore", DeprecationWarning)  # old module names still resolve, with a warning
    parts = dotted.split(".")
    if any(p.startswith("_") for p in parts):
        return None
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for a in parts[i:]:
                obj = getattr(obj, a)
        except AttributeError:
            return None
        return obj if inspect.isfunction(obj) else None
    return None


def _parameters(args: str) -> list[str]:
    """Parameter names of a signature written in the docs: ``path, spec=None, *, x`` → ``["path", "spec", "*", "x"]``."""
    out, depth, cur = [], 0, ""
    for ch in args + ",":
        if ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        if ch == "," and depth == 0:
            name = re.split(r"[=:]", cur, maxsplit=1)[0].strip()
            if name:
                out.append(name.lstrip("*") if name not in ("*",) else name)
            cur = ""
        else:
            cur += ch
    return out


def _signature_names(func) -> list[str]:
    import inspect

    names = []
    for p in inspect.signature(func).parameters.values():
        if p.kind is p.KEYWORD_ONLY and "*" not in names and not any(
                q.kind is q.VAR_POSITIONAL for q in inspect.signature(func).parameters.values()):  # fmt: skip
            names.append("*")
        names.append(p.name)
    return names


def test_every_public_function_the_docs_name_is_shown_with_its_signature():
    """A page that names a fog-gym function (``fog_gym.dataset.decode.load_channel``) writes it once with its whole
    signature (``load_channel(path, spec)``, defaults may be shown); a call written with ``...`` hides it."""
    problems = []
    for page in PAGES:
        text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)  # code blocks run as they are (tested above)
        named, shown = {}, set()
        for m in _CALL.finditer(text):
            func = _public_function(m["name"]) if m["name"].startswith("fog_gym.") else None
            if func is None and m["args"] is not None:
                func = named.get(m["name"]) or _public_function(f"fog_gym.{m['name']}")
            if func is None:
                continue
            named[func.__name__] = func
            args = m["args"]
            if args is not None and "..." in args:
                problems.append(f"{page.relative_to(ROOT)}: `{m['name']}({args})` elides the signature")
            elif args is not None and _parameters(args) == _signature_names(func):
                shown.add(func)
        problems += [f"{page.relative_to(ROOT)}: {f.__module__}.{f.__name__} never shown as "
                     f"{f.__name__}({', '.join(_signature_names(f))})" for f in set(named.values()) - shown]  # fmt: skip
    assert sorted(problems) == []
