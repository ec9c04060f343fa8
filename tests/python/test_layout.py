"""The shape of the code and of the tests: the cmlt package has no import cycle
(between modules, nor between its subpackages), and every test module's
basename is unique across tests/ (pytest's default import mode needs it)."""
from __future__ import annotations

import ast
from collections import Counter
from pathlib import Path

import support

SRC = support.ROOT / "src" / "cmlt"


def _modules():
    """{dotted module name: path} of src/cmlt (packages by their __init__)."""
    out = {}
    for path in SRC.rglob("*.py"):
        parts = list(path.relative_to(SRC.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def import_graph():
    """Module -> the cmlt modules it imports, at module level or inside functions
    (``from . import x`` of a submodule counts as importing the submodule)."""
    mods = _modules()
    known = set(mods) | {"cmlt._core"}
    graph = {}
    for name, path in mods.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if a.name in known}
            elif isinstance(node, ast.ImportFrom):
                base = package.split(".")
                if node.level:
                    base = base[:len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else [])) if node.level \
                    else node.module
                subs = {f"{mod}.{a.name}" for a in node.names} & known
                deps |= subs
                if len(subs) < len(node.names) and mod in known:
                    deps.add(mod)
        graph[name] = deps - {name}
    return graph


def _cycles(graph):
    """The import cycles of ``graph``: its strongly connected components of more
    than one node, each as a sorted tuple (Tarjan's algorithm)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(tuple(sorted(comp)))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(out)


#: cycles known and owned elsewhere (none: a new cycle fails the test)
KNOWN_CYCLES = []


def test01_no_import_cycle_between_modules():
    graph = import_graph()
    assert len(graph) > 40                          # the walk found the package
    assert "cmlt.usd.frame" in graph["cmlt.usd.info"]
    assert [c for c in _cycles(graph) if c not in KNOWN_CYCLES] == []


def test02_no_import_cycle_between_subpackages():
    def top(m):
        return ".".join(m.split(".")[:2])
    graph = {}
    for a, deps in import_graph().items():
        graph.setdefault(top(a), set()).update(top(b) for b in deps if top(b) != top(a))
    assert _cycles(graph) == []


def test03_the_cycle_check_can_fail():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [("a", "b", "c")]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test04_test_module_basenames_are_unique():
    names = Counter(p.name for p in (support.ROOT / "tests").rglob("test_*.py"))
    assert names and not [n for n, k in names.items() if k > 1]


def _pyproject():
    import tomllib
    with open(support.ROOT / "pyproject.toml", "rb") as fh:
        return tomllib.load(fh)


def test05_the_version_is_pyprojects():
    import cmlt
    assert cmlt.__version__ == _pyproject()["project"]["version"]


def test06_the_makefile_installs_pyprojects_build_requirements_and_test_extra():
    """The Makefile names no package of its own: the build requirements (needed for
    --no-build-isolation) are pyproject's, and the rest comes from `.[test]`."""
    import re
    make = (support.ROOT / "Makefile").read_text()
    reqs = re.search(r"^BUILD_REQS\s*:=\s*(.*)$", make, re.M).group(1)
    assert re.findall(r'"([^"]+)"', reqs) == _pyproject()["build-system"]["requires"]
    assert "-e '.[test]'" in make
    extras = _pyproject()["project"]["optional-dependencies"]
    assert "matplotlib" in extras["plot"] and set(extras["plot"]) <= set(extras["test"])
    assert not any(d.startswith("matplotlib") for d in _pyproject()["project"]["dependencies"])
