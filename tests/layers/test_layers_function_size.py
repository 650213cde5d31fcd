"""Issue 43's size rule, read from the source: no function over 120 lines or with over 10
parameters in ``scm_core/inference``, ``services`` and ``worker``; in ``scm_core/simulator``
none over 150 lines or 12 parameters (its numba kernels pass state as arrays). ``self`` and
``cls`` do not count; ``*args`` and ``**kwargs`` count one each. And issue 72's: no module
over 600 lines outside tests and migrations."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from layer_support import parse_file

ROOT = Path(__file__).resolve().parents[2]

#: folder -> (most lines, most parameters) of one function
LIMITS = {
    "scm_core/inference": (120, 10),
    "services": (120, 10),
    "worker": (120, 10),
    "scm_core/simulator": (150, 12),
}


def parameter_count(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = fn.args
    names = [*a.posonlyargs, *a.args, *a.kwonlyargs]
    n = len(names) + (a.vararg is not None) + (a.kwarg is not None)
    return n - (1 if names and names[0].arg in ("self", "cls") else 0)


def oversized(tree: ast.Module, max_lines: int, max_params: int) -> list[str]:
    """``name (N lines, P parameters)`` of every function of ``tree`` over a limit."""
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            lines = node.end_lineno - node.lineno + 1
            params = parameter_count(node)
            if lines > max_lines or params > max_params:
                out.append(f"{node.name} (line {node.lineno}: {lines} lines, {params} parameters)")
    return out


@pytest.mark.parametrize("folder", sorted(LIMITS))
def test_no_function_is_over_the_size_limits(folder: str) -> None:
    max_lines, max_params = LIMITS[folder]
    found = [
        f"{path.relative_to(ROOT)}: {what}"
        for path in sorted((ROOT / folder).rglob("*.py"))
        for what in oversized(parse_file(path), max_lines, max_params)
    ]
    assert not found, "\n".join(found)


def test_the_rule_catches_a_long_function_and_a_long_signature() -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(125))
    tree = ast.parse(
        f"def long():\n{body}\n\ndef wide(self, a, b, c, d, e, f, g, h, i, j, *k):\n    pass\n"
    )
    found = oversized(tree, 120, 10)
    assert found == [
        "long (line 1: 126 lines, 0 parameters)",
        "wide (line 128: 2 lines, 11 parameters)",
    ]


#: most lines of one module outside tests and migrations (issue 72): a module is one job
MODULE_LINES = 600
MODULE_FOLDERS = ("scm_core", "services", "worker", "benchmarks")


def oversized_modules(paths: list[Path], limit: int) -> list[str]:
    """``path (N lines)`` of every file of ``paths`` over ``limit`` lines."""
    out = []
    for path in paths:
        n = len(path.read_text(encoding="utf-8").splitlines())
        if n > limit:
            out.append(
                f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path} ({n} lines)"
            )
    return out


def test_no_module_is_over_600_lines() -> None:
    paths = sorted(p for folder in MODULE_FOLDERS for p in (ROOT / folder).rglob("*.py"))
    assert len(paths) > 150
    found = oversized_modules(paths, MODULE_LINES)
    assert not found, "split these modules:\n" + "\n".join(found)


def test_the_module_rule_catches_a_long_module(tmp_path: Path) -> None:
    long = tmp_path / "long.py"
    long.write_text("x = 1\n" * 601, encoding="utf-8")
    short = tmp_path / "short.py"
    short.write_text("x = 1\n" * 600, encoding="utf-8")
    assert oversized_modules([long, short], MODULE_LINES) == [f"{long} (601 lines)"]
