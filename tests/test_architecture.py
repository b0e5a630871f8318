"""The package's shape: import layers (import-linter), no import cycle, few top-level modules.

The layer and independence contracts live in ``pyproject.toml`` (``[tool.importlinter]``);
``lint-imports`` checks them from the command line and :func:`test_import_contracts_hold`
here, so the README's test command checks them too. Cycles are found on grimp's import
graph (the one import-linter builds), which holds every import of a module, those inside
functions included: a lazy import cannot hide a cycle.
"""

from __future__ import annotations

import pkgutil
import re
import subprocess
import sys
from pathlib import Path

import grimp

import hmmtrack

ROOT = Path(hmmtrack.__file__).resolve().parents[1]
#: plain modules allowed at the top of the package (REDESIGN.md: at most 8)
MAX_TOP_LEVEL_MODULES = 8


def strongly_connected_components(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's algorithm (iterative): the components of a directed graph, each a list of
    nodes; a node alone is a component of one unless it imports itself."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    components = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                components.append(component)
    return components


def test_strongly_connected_components_finds_cycles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    components = sorted(sorted(c) for c in strongly_connected_components(graph))
    assert components == [["a", "b", "c"], ["d"], ["e"]]


def import_graph() -> dict[str, set[str]]:
    """Module -> modules of the package it imports (anywhere in its body)."""
    graph = grimp.build_graph("hmmtrack")
    return {m: set(graph.find_modules_directly_imported_by(m)) for m in graph.modules}


def test_no_import_cycle():
    graph = import_graph()
    cycles = [sorted(c) for c in strongly_connected_components(graph) if len(c) > 1]
    # a package imports its own modules from __init__; a cycle through a package face
    # and its children is still a cycle (the face must not be imported back)
    assert cycles == [], f"import cycles: {cycles}"


def test_import_contracts_hold():
    """``lint-imports`` with the project's contracts exits 0 (its report is shown on failure).

    It runs in a child process: import-linter configures logging when it runs, which would
    change the log capture of the tests that run after this one."""
    done = subprocess.run(
        [sys.executable, "-c", "import sys; from importlinter.cli import lint_imports_command;"
         " sys.argv = ['lint-imports', '--no-cache']; lint_imports_command()"],
        cwd=ROOT, capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    report = done.stdout + done.stderr
    assert done.returncode == 0, report
    assert re.search(r"Contracts: (\d+) kept, 0 broken", report), report
    assert int(re.search(r"Contracts: (\d+) kept", report).group(1)) >= 2


def test_few_plain_modules_at_the_top():
    top = [m.name for m in pkgutil.iter_modules(hmmtrack.__path__) if not m.ispkg]
    assert len(top) <= MAX_TOP_LEVEL_MODULES, top
