"""The package's modules import one another one way only, and the reporting modules stay small.

The graph holds every ``import`` of a ``radar2shape`` module, function-level ones included (a lazy
import still ties the two modules together). One kind of edge is left out: a package's
``__init__`` importing its own submodules. A package re-exports its parts and the parts take shared
names from the package, so that pair is always a loop; loops between modules, or between a module
and another package, still fail.
"""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = "radar2shape"
MAX_REPORTING_LINES = 400


def module_names(root: Path, package: str) -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` under ``root/package`` (packages by their ``__init__``)."""
    modules = {}
    for path in sorted((root / package).rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def imported_modules(name: str, path: Path, known: set[str]) -> set[str]:
    """The modules of ``known`` that ``name`` (at ``path``) imports anywhere in its body."""
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: the package of this module, less one level per extra dot
                anchor = name.split(".") if is_package else name.split(".")[:-1]
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base for alias in node.names]
        else:
            continue
        for target in targets:
            while target and target not in known:  # ``import a.b.func``-style names: the module that holds them
                target = target.rpartition(".")[0]
            if target:
                found.add(target)
    return found


def import_graph(root: Path, package: str) -> dict[str, set[str]]:
    """Module -> the package modules it imports, without a package's edges to its own submodules."""
    modules = module_names(root, package)
    graph = {}
    for name, path in modules.items():
        targets = imported_modules(name, path, set(modules)) - {name}
        if path.name == "__init__.py":
            targets = {t for t in targets if not t.startswith(name + ".")}
        graph[name] = targets
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle as ``[a, b, ..., a]``, or None (depth-first search, modules in sorted order)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (cycle := visit(nxt)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (cycle := visit(start)):
            return cycle
    return None


def test_no_import_cycle_between_modules():
    cycle = find_cycle(import_graph(SRC, PACKAGE))
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_reporting_modules_stay_small():
    long = {str(p.relative_to(SRC)): n for p in sorted((SRC / PACKAGE / "reporting").rglob("*.py"))
            if (n := len(p.read_text().splitlines())) > MAX_REPORTING_LINES}
    assert not long, f"reporting modules over {MAX_REPORTING_LINES} lines: {long}"


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)


def test_cycle_finder_names_a_cycle_between_submodules(tmp_path):
    _write(tmp_path, {
        "pkg/__init__.py": "from pkg.sub import a\n",  # an __init__ re-exporting its submodule: allowed
        "pkg/sub/__init__.py": "from .a import thing\n",
        "pkg/sub/a.py": "from pkg import shared, name\nthing = 1\n",  # a module and a name of pkg
        "pkg/shared.py": "def f():\n    from .sub.b import g  # lazy, still an edge\n",
        "pkg/sub/b.py": "from . import a\nimport pkg.shared\ng = 2\n",
    })
    graph = import_graph(tmp_path, "pkg")
    assert graph["pkg"] == set() and graph["pkg.sub"] == set()
    assert graph["pkg.sub.a"] == {"pkg", "pkg.shared"}
    assert graph["pkg.shared"] == {"pkg.sub.b"} and graph["pkg.sub.b"] == {"pkg.sub.a", "pkg.shared"}
    assert find_cycle(graph) == ["pkg.shared", "pkg.sub.b", "pkg.shared"]


def test_cycle_finder_passes_one_way_imports(tmp_path):
    _write(tmp_path, {
        "pkg/__init__.py": "from pkg.a import x\nfrom pkg.b import y\n",
        "pkg/a.py": "x = 1\n",
        "pkg/b.py": "from pkg import x\nfrom pkg.a import x as z\ny = 2\n",
    })
    assert find_cycle(import_graph(tmp_path, "pkg")) is None
