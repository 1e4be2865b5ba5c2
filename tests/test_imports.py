"""The project's import graph: layers point one way and nothing imports in a circle.

The graph is read from the source (every ``import`` anywhere in a module, also those
inside functions, which still close a circle when they run), over the packages
``sdc_gym``, ``sdc_agents``, ``sdc_evaluation`` and ``sdc_training`` (the folders
``sdc_gym/``, ``agents/``, ``evaluation/`` and ``training/``: pyproject's package-dir) and
the scripts ``evaluate.py`` and ``train.py``. ``from package import name`` counts as
importing ``package.name`` when that is a module, else ``package`` itself.
"""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"sdc_gym": "sdc_gym", "sdc_agents": "agents", "sdc_evaluation": "evaluation",
            "sdc_training": "training"}
"""Import name -> folder."""
SCRIPTS = {"sdc_gym_cli.evaluate": "evaluate.py", "sdc_gym_cli.train": "train.py"}
"""The scripts, by their installed names (pyproject maps sdc_gym_cli onto the repo's root)."""
COMMANDS = "commands"
"""The layer of the scripts and of the packages' ``__main__`` modules that run them."""
SDC_CONFIGS = "sdc_configs"  # the configs folder's resolver: imports nothing of the project


@cache
def module_files() -> dict[str, Path]:
    modules = {name: ROOT / file for name, file in SCRIPTS.items()}
    modules[SDC_CONFIGS] = ROOT / "configs" / "__init__.py"
    for package, folder in PACKAGES.items():
        for path in (ROOT / folder).rglob("*.py"):
            parts = [package, *path.relative_to(ROOT / folder).with_suffix("").parts]
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
    assert "sdc_evaluation.runner" in graph
    assert "sdc_agents.registry" in graph["sdc_evaluation.episodes"]
    pruned = {}
    for name, targets in graph.items():
        package = name if _is_package(module_files()[name]) else name.rpartition(".")[0]
        pruned[name] = {t for t in targets if not _own_package(t, package)}
    assert find_cycle(pruned) is None


def layer(module: str) -> str:
    """The package of ``module``, or :data:`COMMANDS` for the scripts and ``__main__``s."""
    return COMMANDS if module in SCRIPTS or module.endswith(".__main__") else \
        module.split(".")[0]


def package_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for name, targets in import_graph().items():
        top = layer(name)
        graph.setdefault(top, set()).update(layer(t) for t in targets if layer(t) != top)
    return graph


def test_the_layers_point_one_way():
    graph = package_graph()
    assert graph["sdc_gym"] == set(), "sdc_gym imports nothing of agents or evaluation"
    assert graph["sdc_agents"] == {"sdc_gym"}
    assert graph["sdc_evaluation"] == {"sdc_agents", "sdc_gym"}
    assert graph["sdc_training"] <= {"sdc_agents", "sdc_evaluation", "sdc_gym"}
    assert graph[SDC_CONFIGS] == set()
    assert graph[COMMANDS] >= {"sdc_agents", "sdc_evaluation", "sdc_training", SDC_CONFIGS}
    assert not any("sdc_training" in targets for name, targets in graph.items()
                   if name not in ("sdc_training", COMMANDS)), "only the scripts use training"
    assert find_cycle(graph) is None


@pytest.mark.parametrize("module", sorted(m for m in module_files() if
                                          m.startswith("sdc_evaluation")))
def test_evaluation_reaches_agents_only_through_the_registry(module):
    reached = {t for t in import_graph()[module] if t.split(".")[0] == "sdc_agents"}
    assert reached <= {"sdc_agents.registry"}, f"{module} imports {sorted(reached)}"
