"""sotdrake's modules import one another without a cycle: module-level imports (those run when a
module is imported, and the types a module imports for the type checker in ``if TYPE_CHECKING:``;
imports inside functions aside, and a package's ``__init__`` type-checking block, which mirrors the
names it imports lazily) form a graph without a cycle, so each module can be read, and loaded,
after the ones it uses."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "sotdrake"


def module_names() -> dict[str, Path]:
    """Every module of sotdrake, by dotted name (a package by its own name)."""
    modules = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        modules[".".join(parts)] = path
    return modules


def _top_level(body: list[ast.stmt], package_init: bool = False):
    """The statements run at import: the module's own, and those of its ``if``/``try``/``with``
    blocks (not those of functions or classes); with ``package_init``, not those of an
    ``if TYPE_CHECKING:`` block."""
    for node in body:
        if package_init and isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            yield from _top_level(node.orelse, package_init)
            continue
        yield node
        for block in ("body", "orelse", "finalbody", "handlers"):
            inner = getattr(node, block, None)
            if isinstance(inner, list) and not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                yield from _top_level([n for n in inner if isinstance(n, ast.stmt)] + [
                    s for h in inner if isinstance(h, ast.ExceptHandler) for s in h.body], package_init)


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The sotdrake modules ``name`` imports at module level."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in _top_level(ast.parse(path.read_text()).body, path.name == "__init__.py"):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            submodules = {f"{target}.{alias.name}" for alias in node.names} & modules.keys()
            found |= submodules
            if len(submodules) < len(node.names):  # (``from . import a`` of submodules needs only them)
                found.add(target)
    return {m for m in found if m in modules and m != name}


def import_graph() -> dict[str, set[str]]:
    modules = module_names()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` (its modules in order, the first repeated at the end), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                cycle = visit(nxt)
                if cycle:
                    return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def test_the_graph_reads_type_checking_imports(tmp_path):
    module = tmp_path / "levels.py"
    module.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .solver import Contact\n"
                      "def f():\n    from .gains import g\n")
    modules = {"pkg.levels": module, "pkg.solver": module, "pkg.gains": module}
    assert imports_of("pkg.levels", module, modules) == {"pkg.solver"}


def test_the_finder_sees_a_cycle_and_a_tree():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_the_graph_sees_relative_and_absolute_imports():
    graph = import_graph()
    assert len(graph) > 100
    assert "sotdrake.entity" in graph["sotdrake.gains"]  # from .entity import Entity
    assert "sotdrake.dynamics.formulation" in graph["sotdrake.dynamics.solver_dyn"]
    assert "sotdrake.robots.model" in graph["sotdrake.robots.loader"]


def test_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])
