"""The package reads as the pipeline: no import cycle (function-level imports count, so an
import inside a function cannot hide one), and the stages import only downward
(the import-linter contract in pyproject.toml)."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import grimp
from importlinter import cli as importlinter_cli

ROOT = Path(__file__).resolve().parents[1]


def _cycles(graph) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    edges = {m: sorted(graph.find_modules_directly_imported_by(m)) for m in graph.modules}
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                on.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                found.append(sorted(part))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10_000))
    try:
        for m in sorted(edges):
            if m not in index:
                visit(m)
    finally:
        sys.setrecursionlimit(limit)
    return found


def test_no_module_imports_itself_back():
    graph = grimp.build_graph("ncopt")
    assert len(graph.modules) > 40  # the whole package was read
    assert _cycles(graph) == []


def test_a_planted_cycle_is_found():
    """The check itself: a back-edge added to the real graph makes a cycle it reports."""
    graph = grimp.build_graph("ncopt")
    graph.add_import(importer="ncopt.runtime.errors", imported="ncopt.api")
    assert any("ncopt.api" in c and "ncopt.runtime.errors" in c for c in _cycles(graph))


def test_the_stages_import_only_downward(monkeypatch):
    monkeypatch.chdir(ROOT)
    assert importlinter_cli.lint_imports(config_filename=str(ROOT / "pyproject.toml")) == 0


MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80


def _sizes():
    """(module lines over the limit, functions over the limit) in the package."""
    big_modules, long_functions = [], []
    for path in sorted((ROOT / "ncopt").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        rel = path.relative_to(ROOT).as_posix()
        if len(text.splitlines()) > MAX_MODULE_LINES:
            big_modules.append((rel, len(text.splitlines())))
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    long_functions.append((rel, node.name, length))
    return big_modules, long_functions


def test_no_module_over_600_lines_and_no_function_over_80():
    assert _sizes() == ([], [])
