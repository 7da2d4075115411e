"""The import structure: no cycles between modules or between subpackages, and the layering of the data path.

Every ``import`` counts, including those inside functions (a lazy import hides a cycle from Python, not from
the design). ``wrappers/`` is the ``fog_gym.wrappers`` package.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: The dataset format layer: reads and writes the FogDrive layout, knows nothing of how the data was made.
FORMAT_LAYER = ("fog_gym.dataset",)
#: Pure physics and geometry: numpy in, numpy out.
PURE = ("fog_gym._numba", "fog_gym.channels.spec", "fog_gym.checks", "fog_gym.geometry", "fog_gym.world.primitives", "fog_gym.fog.physics",
        "fog_gym.fog.camera", "fog_gym.fog.glow", "fog_gym.fog.lidar", "fog_gym.fog.lidar_field", "fog_gym.fog.lidar_grid", "fog_gym.fog.lidar_pulse",
        "fog_gym.fog.lidar_bank", "fog_gym.fog.lidar_height", "fog_gym.fog.depth", "fog_gym.fog.returns",
        "fog_gym.fog.fields", "fog_gym.fog.schedules", "fog_gym.fog.vexp", "fog_gym.encoding",
        "fog_gym.seeds", "fog_gym._rounds")  # fmt: skip
#: What builds or runs an environment (the format layer and the pure modules may import none of it).
ENVIRONMENT = ("fog_gym.envs", "fog_gym.world.traffic_world", "fog_gym.world.traffic", "fog_gym.wrappers", "fog_gym.rl",
               "fog_gym.generate")  # fmt: skip


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[0] == "wrappers":
        parts = ["fog_gym", *parts]
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    files = [*ROOT.glob("fog_gym/**/*.py"), *ROOT.glob("wrappers/**/*.py")]
    out = {_module_name(p): p for p in files if "__pycache__" not in p.parts}
    return {name: p for name, p in out.items() if not name.startswith("fog_gym.wrappers.wrappers")}


def import_graph() -> dict[str, set[str]]:
    """Module → the project modules it imports anywhere in its body (``from a import b`` counts ``a.b`` when that
    is a module, else ``a``)."""
    mods = _modules()
    graph: dict[str, set[str]] = {}
    for name, path in mods.items():
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("fog_gym"):
                subs = {f"{node.module}.{a.name}" for a in node.names} & mods.keys()
                deps |= subs
                if len(subs) < len(node.names):
                    deps.add(node.module)
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if a.name.startswith("fog_gym")}
        graph[name] = {d for d in deps if d in mods and d != name}
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one node (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for start in sorted(graph):
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def _folder(module: str) -> str:
    """A subpackage's modules collapse to the subpackage; modules at the top of ``fog_gym`` stay themselves."""
    parts = module.split(".")
    return ".".join(parts[:2])


def _under(module: str, prefixes: tuple[str, ...]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in prefixes)


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph()


def test_the_cycle_finder_finds_a_known_cycle_and_nothing_in_a_chain():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_the_graph_sees_lazy_imports_and_the_wrappers_folder(graph):
    assert "fog_gym.wrappers.fog" in graph["fog_gym.envs.presets"]  # imported inside make_fogdrive
    assert "fog_gym.wrappers.record" in graph and "fog_gym.dataset.writer" in graph["fog_gym.wrappers.record"]


def test_no_module_imports_itself_back(graph):
    assert cycles(graph) == []


def test_no_subpackage_imports_itself_back(graph):
    folders: dict[str, set[str]] = {}
    for mod, deps in graph.items():
        folders.setdefault(_folder(mod), set()).update(_folder(d) for d in deps if _folder(d) != _folder(mod))
    assert cycles(folders) == []


def test_the_dataset_format_layer_imports_neither_the_env_nor_the_wrappers(graph):
    leaks = sorted((m, d) for m, deps in graph.items() if _under(m, FORMAT_LAYER) for d in deps if _under(d, ENVIRONMENT))
    assert leaks == []


def test_pure_physics_and_geometry_import_only_pure_modules(graph):
    leaks = sorted((m, d) for m in PURE for d in graph[m] if not _under(d, PURE))
    assert leaks == []


def test_the_channel_specification_is_the_bottom_of_the_data_path(graph):
    """Sensors, fog and the world read the channel specification (fog_gym.channels), not the dataset layer; the
    specification imports nothing of the project but itself."""
    data_path = ("fog_gym.sensors", "fog_gym.fog", "fog_gym.world")
    upward = sorted((m, d) for m, deps in graph.items() if _under(m, data_path) for d in deps if _under(d, ("fog_gym.dataset",)))
    assert upward == []
    below = sorted((m, d) for m, deps in graph.items() if _under(m, ("fog_gym.channels",))
                   for d in deps if not _under(d, ("fog_gym.channels",)))  # fmt: skip
    assert below == []


def test_env_and_wrappers_do_not_import_each_other(graph):
    env_to_wrappers = [d for d in graph["fog_gym.envs.fogdrive"] if _under(d, ("fog_gym.wrappers",))]
    wrappers_to_env = [(m, d) for m, deps in graph.items() if _under(m, ("fog_gym.wrappers",))
                       for d in deps if d in ("fog_gym.envs.fogdrive", "fog_gym.envs.presets", "fog_gym.envs.presets")]  # fmt: skip
    assert env_to_wrappers == [] and wrappers_to_env == []


def test_at_most_ten_modules_live_directly_under_the_package():
    top = sorted(p.name for p in (ROOT / "fog_gym").glob("*.py") if p.name not in ("__init__.py", "_version.py"))
    assert len(top) <= 10, top


def test_no_module_is_longer_than_600_lines():
    long = sorted((name, n) for name, p in _modules().items() if (n := len(p.read_text().splitlines())) > 600)
    assert long == []


def test_tests_mirror_the_package_folders():
    """Every subpackage with tests has them in the mirrored folder, not as a name prefix at the top of ``tests/``."""
    folders = {p.parent.name for p in (ROOT / "fog_gym").glob("*/__init__.py")} | {"wrappers"}
    prefixed = sorted(p.name for p in (ROOT / "tests").glob("test_*.py")
                      if any(p.name.startswith(f"test_{f.rstrip('s')}") for f in folders))  # fmt: skip
    assert prefixed == []
