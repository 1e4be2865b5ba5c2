"""The project's import graph: layers point one way and nothing imports in a circle.

The graph is read from the source (every ``import`` anywhere in a module, also those
inside functions, which still close a circle when they run), over the packages
``sdc_gym``, ``agents``, ``evaluation`` and ``training`` and the scripts ``evaluate.py``
and ``train.py``. ``from package import name`` counts as importing ``package.name`` when that
is a module, else ``package`` itself.
"""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sdc_gym", "agents", "evaluation", "training")
SCRIPTS = ("evaluate", "train")


@cache
def module_files() -> dict[str, Path]:
    modules = {name: ROOT / f"{name}.py" for name in SCRIPTS}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            modules[".".join(parts)] = path
    return modules


def _is_package(path: Path) -> bool:
    return path.name == "__init__.py"


@cache
def import_graph() -> dict[str, set[str]]:
    """Module -> the project modules it imports."""
    modules = module_files()
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        package = name if _is_package(path) else name.rpartition(".")[0]
        edges: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative import
                    anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join([*anchor, *([base] if base else [])])
                targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules
                           else base for alias in node.names]
            else:
                continue
            for target in targets:
                while target and target not in modules:  # a name inside a module
                    target = target.rpartition(".")[0]
                if target and target != name:
                    edges.add(target)
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle (as a path that ends where it starts), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for target in sorted(graph.get(node, ())):
            if state.get(target) == 1:
                return [*path[path.index(target):], target]
            if target not in state and (cycle := visit(target)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def _own_package(module: str, package: str) -> bool:
    """Whether ``module`` is ``package``'s ``__init__`` or one of its parents' (a module
    importing its own package's ``__init__`` to reach a sibling closes no real circle
    between modules; it is left out of the module graph, kept in the package graph)."""
    return package == module or package.startswith(module + ".")


def test_the_finder_finds_a_constructed_circle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_no_import_circle_among_the_projects_modules():
    graph = import_graph()
    assert "evaluation.runner" in graph and "agents.registry" in graph["evaluation.episodes"]
    pruned = {}
    for name, targets in graph.items():
        package = name if _is_package(module_files()[name]) else name.rpartition(".")[0]
        pruned[name] = {t for t in targets if not _own_package(t, package)}
    assert find_cycle(pruned) is None


def package_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for name, targets in import_graph().items():
        top = name.split(".")[0]
        graph.setdefault(top, set()).update(t.split(".")[0] for t in targets
                                            if t.split(".")[0] != top)
    return graph


def test_the_layers_point_one_way():
    graph = package_graph()
    assert graph["sdc_gym"] == set(), "sdc_gym imports nothing of agents or evaluation"
    assert graph["agents"] == {"sdc_gym"}
    assert graph["evaluation"] == {"agents", "sdc_gym"}
    assert graph["training"] <= {"agents", "evaluation", "sdc_gym"}
    assert not any("training" in targets for name, targets in graph.items()
                   if name not in ("training", *SCRIPTS)), "only the scripts use training"
    assert find_cycle(graph) is None


@pytest.mark.parametrize("module", sorted(m for m in module_files() if
                                          m.startswith("evaluation")))
def test_evaluation_reaches_agents_only_through_the_registry(module):
    reached = {t for t in import_graph()[module] if t.split(".")[0] == "agents"}
    assert reached <= {"agents.registry"}, f"{module} imports {sorted(reached)}"
