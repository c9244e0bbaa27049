"""The house rules of ``src/heatparam`` (docs/architecture.md), checked on the source text: no import cycle between
modules (function-level imports included), no function over 60 lines, no module-level True/False switch, no
history in comments (what was tried and when lives in git and BENCHMARKS.md), few BENCHMARKS links."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = SRC / "heatparam"
MAX_FUNCTION_LINES = 60
MAX_SECTION_LINKS = 40


def _modules() -> dict[str, Path]:
    """Dotted module name → file, for every module of the package."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imported(name: str, path: Path, node: ast.Import | ast.ImportFrom) -> set[str]:
    """The package's modules an import statement of module ``name`` names (``from pkg import sub`` names
    ``pkg.sub`` when that is a module, else ``pkg``); importing a submodule does not count as importing its
    package's ``__init__``."""
    if isinstance(node, ast.ImportFrom):
        if node.level:
            base = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
            base = base[: len(base) - node.level + 1]
            mod = ".".join(base + ([node.module] if node.module else []))
        else:
            mod = node.module or ""
        targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in MODULES else mod for a in node.names]
    else:
        targets = [a.name for a in node.names]
    found = set()
    for t in targets:
        while t and t not in MODULES:
            t = t.rpartition(".")[0]
        if t and t != name:
            found.add(t)
    return found


def import_graph() -> dict[str, set[str]]:
    """Module → the package's modules it imports anywhere in its text (top level or inside functions)."""
    graph = {}
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        graph[name] = set().union(*(_imported(name, path, n) for n in ast.walk(tree)
                                    if isinstance(n, ast.Import | ast.ImportFrom)))
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
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
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_two_modules_import_each_other():
    graph = import_graph()
    assert "heatparam.refine.newton" in graph["heatparam.refine.multilevel"]  # the graph is read
    assert cycles(graph) == []


def _functions():
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                yield f"{name}.{node.name} (line {node.lineno})", node.end_lineno - node.lineno + 1


def test_no_function_over_60_lines():
    long = {f: n for f, n in _functions() if n > MAX_FUNCTION_LINES}
    assert not long, long


def test_no_module_level_switch():
    """A module-level constant ``NAME = True/False`` is an experiment's switch: the code takes one branch, the
    other is dead (decided switches are deleted, their branch hard-wired). Lower-case names are state."""
    found = []
    for name, path in MODULES.items():
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            target = node.targets[0] if isinstance(node, ast.Assign) and len(node.targets) == 1 else \
                node.target if isinstance(node, ast.AnnAssign) else None
            value = getattr(node, "value", None)
            if (isinstance(target, ast.Name) and target.id.isupper() and isinstance(value, ast.Constant)
                    and isinstance(value.value, bool)):
                found.append(f"{name}.{target.id}")
    assert not found, found


HISTORY = re.compile(r"\b(stop|round) \d+\b|\b20\d\d-\d\d-\d\d\b|\bas before\b|\buntil stop\b", re.IGNORECASE)


@pytest.mark.parametrize("name", sorted(MODULES))
def test_no_history_in_the_source(name):
    """Comments say why; what was tried, when and in which round is in git and BENCHMARKS.md."""
    hits = [f"{i}: {line.strip()}" for i, line in enumerate(MODULES[name].read_text(encoding="utf-8").splitlines(), 1)
            if HISTORY.search(line)]
    assert not hits, hits


def test_few_benchmark_links_in_the_source():
    links = sum(p.read_text(encoding="utf-8").count("§") for p in MODULES.values())
    assert links <= MAX_SECTION_LINKS, links
