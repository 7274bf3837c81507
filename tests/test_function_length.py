"""No package function is longer than 80 lines (numba kernels aside: a compiled kernel is one loop
that numba cannot call into smaller Python functions without a cost per call)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "sotdrake"
LIMIT = 80


def _compiled(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    return any("jit" in ast.unparse(decorator) for decorator in node.decorator_list)


def long_functions(root: Path = PACKAGE, limit: int = LIMIT) -> list[str]:
    """``path:line name (length)`` of every function over ``limit`` lines below ``root``."""
    found = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _compiled(node):
                length = node.end_lineno - node.lineno + 1
                if length > limit:
                    found.append(f"{path.relative_to(root.parent)}:{node.lineno} {node.name} ({length} lines)")
    return found


def test_no_package_function_is_over_80_lines():
    assert long_functions() == []


def test_the_check_finds_a_long_function_and_spares_a_kernel(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(85))
    (tmp_path / "long.py").write_text(f"def long():\n{body}\n\n\n@njit(cache=True)\ndef kernel():\n{body}\n")
    assert [line.split(" ")[1] for line in long_functions(tmp_path)] == ["long"]
