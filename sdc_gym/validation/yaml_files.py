"""The one YAML loader of sdc-gym: every YAML file or value the project reads (env and run
configs, hyperparameter and sweep files, scenario files, light configs, a policy's
``config.yaml``, ``--hp key=value``) goes through :func:`parse_yaml_lines`.

What a hostile YAML text can cost is bounded before anything is built from it:

* its size: at most :data:`MAX_YAML_BYTES` (PyYAML's pure-Python parser reads about
  100 kB/s on a loaded 2-core machine; the project's largest YAML file is 2 kB);
* its nesting: at most :data:`MAX_YAML_DEPTH` levels, checked while composing (a
  ``[[[[...`` text otherwise ends in a ``RecursionError``);
* its nodes: at most :data:`MAX_YAML_NODES`, counted while composing;
* its aliases: the document *as expanded* (every alias counted as the whole node it
  names) has at most :data:`MAX_YAML_NODES` nodes. A "billion laughs" file (352 bytes of
  nested aliases, 10^9 leaves) is refused after composing its ~100 nodes, by a count
  memoized per node, before any value is constructed or walked (it hung evaluate.py);
  a recursive alias (``&a [*a]``) is refused too;
* duplicate keys in a mapping are refused with the key and both lines (PyYAML keeps the
  last one silently: ``duration: 6`` ... ``duration: 20`` ran 20 s).

Numbers are read as YAML 1.2 reads them: ``1e-4`` is a float (PyYAML's YAML 1.1 resolver
makes it the string ``"1e-4"``, which a learning rate then rejects far from the cause).
The loader is a ``SafeLoader``: data only, never Python objects.
"""

from __future__ import annotations

import os
import re
from typing import Any, Final

import yaml

from sdc_gym.config import excerpt, shorten
from sdc_gym.validation.text_files import read_text

MAX_YAML_BYTES: Final = 256 * 1024
"""The largest YAML text read (256 KiB; parsed in under 3 s on the loaded machine)."""
MAX_YAML_DEPTH: Final = 64
"""Nesting levels of collections in a YAML document."""
MAX_YAML_NODES: Final = 50_000
"""Nodes of a YAML document, composed and with every alias expanded (a scenario of
1,000 cars, the traffic's bound: 9,000). PyYAML composes about 6,000 nodes a second on the
loaded 2-core machine, so a file costs at most some 8 s (``benchmarks/hostile_costs.py``)."""


class YamlLimitError(yaml.YAMLError):
    """A YAML text beyond one of the loader's bounds, or with a duplicate key; its message
    names the line."""

    def __init__(self, line: int | None, message: str) -> None:
        super().__init__(message)
        self.line = line
        self.message = message

    def __str__(self) -> str:
        return self.message


class SafeYamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2's floats, bounded nesting and no duplicate keys
    (the alias bound is checked on the composed node graph by :func:`compose`)."""

    _depth = 0
    _composed = 0

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node:
        self._composed += 1
        if self._composed > MAX_YAML_NODES:  # before the time to compose them is spent
            mark = self.peek_event().start_mark
            raise YamlLimitError(mark.line + 1, f"line {mark.line + 1}: the document has "
                                 f"more than {MAX_YAML_NODES:,} nodes (the bound of every "
                                 "YAML file)")
        if self._depth >= MAX_YAML_DEPTH:
            mark = self.peek_event().start_mark
            raise YamlLimitError(mark.line + 1, f"line {mark.line + 1}: nested deeper than "
                                 f"{MAX_YAML_DEPTH} levels (the bound of every YAML file)")
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        if isinstance(node, yaml.MappingNode):
            first_line: dict[Any, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    hash(key)
                except TypeError:
                    continue  # the base class names the unhashable key
                line = key_node.start_mark.line + 1
                if key in first_line:
                    raise YamlLimitError(line, f"line {line}: duplicate key {excerpt(key)} "
                                         f"(first at line {first_line[key]}); each key may "
                                         "appear once in a mapping")
                first_line[key] = line
        return super().construct_mapping(node, deep=deep)


SafeYamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                  |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                  |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                  |[-+]?\.(?:inf|Inf|INF)
                  |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def expanded_size(root: yaml.Node, limit: int = MAX_YAML_NODES) -> int:
    """The nodes of ``root``'s document with every alias expanded, counted once per
    distinct node (memoized): linear in the composed graph, whatever the expansion.
    :class:`YamlLimitError` past ``limit`` or for a node that contains itself."""
    sizes: dict[int, int] = {}
    active: set[int] = set()

    def size(node: yaml.Node) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in active:
            line = node.start_mark.line + 1
            raise YamlLimitError(line, f"line {line}: a recursive alias (a node that "
                                 "contains itself)")
        active.add(key)
        total = 1
        if isinstance(node, yaml.SequenceNode):
            total += sum(size(item) for item in node.value)
        elif isinstance(node, yaml.MappingNode):
            total += sum(size(k) + size(v) for k, v in node.value)
        active.discard(key)
        if total > limit:
            line = node.start_mark.line + 1
            raise YamlLimitError(line, f"line {line}: the document expands to more than "
                                 f"{limit:,} nodes (aliases counted as what they name; the "
                                 "bound of every YAML file)")
        sizes[key] = total
        return total

    return size(root)


def check_yaml_size(text: str) -> None:
    """:class:`YamlLimitError` for a text longer than :data:`MAX_YAML_BYTES`."""
    size = len(text.encode("utf-8", "surrogatepass"))
    if size > MAX_YAML_BYTES:
        raise YamlLimitError(None, f"the YAML text is {size:,} bytes; at most "
                             f"{MAX_YAML_BYTES:,} are read (is this the right file?)")


def parse_yaml_lines(text: str) -> tuple[Any, dict[str, int]]:
    """YAML text to Python values (within every bound above) and the line (1-based) of
    every key and list item, by key path (``"cars[2].speed"``; ``""`` is the document),
    read from PyYAML's node tree so that errors can name the line. Raises a
    ``yaml.YAMLError`` (a :class:`YamlLimitError` for the bounds)."""
    check_yaml_size(text)
    loader = SafeYamlLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None, {}
        expanded_size(node)
        data = loader.construct_document(node)
    finally:
        loader.dispose()
    lines: dict[str, int] = {}
    _node_lines(node, "", lines)
    return data, lines


def parse_yaml(text: str) -> Any:
    """YAML text to Python values (see :func:`parse_yaml_lines`)."""
    return parse_yaml_lines(text)[0]


def _node_lines(node: yaml.Node, path: str, lines: dict[str, int]) -> None:
    lines.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        for key, value in node.value:
            name = f"{path}.{key.value}" if path else str(key.value)
            lines[name] = key.start_mark.line + 1
            _node_lines(value, name, lines)
    elif isinstance(node, yaml.SequenceNode):
        for index, item in enumerate(node.value):
            _node_lines(item, f"{path}[{index}]", lines)


def yaml_problem_text(source: str | os.PathLike[str], what: str,
                      problem: yaml.YAMLError) -> str:
    """``FILE:LINE: the WHAT is not valid YAML (...)`` or, for a bound, ``FILE:LINE: the
    WHAT ...`` with the bound."""
    if isinstance(problem, YamlLimitError):
        where = f"{source}:{problem.line}" if problem.line is not None else f"{source}"
        detail = problem.message.split(": ", 1)[1] if problem.line is not None else \
            problem.message
        return f"{where}: the {what} is refused: {detail}"
    mark = getattr(problem, "problem_mark", None)
    where = f"{source}:{mark.line + 1}" if mark is not None else f"{source}"
    return f"{where}: the {what} is not valid YAML ({shorten(str(problem), 400)})"


def read_yaml_lines(path: str | os.PathLike[str], what: str,
                    error: type[Exception] = ValueError) -> tuple[Any, dict[str, int]]:
    """A YAML file's content and its lines by key path (see :func:`parse_yaml_lines`);
    ``error`` (naming the file and line) for an unreadable file, invalid YAML or a bound."""
    text = read_text(path, what, error, max_bytes=MAX_YAML_BYTES)
    try:
        return parse_yaml_lines(text)
    except yaml.YAMLError as problem:
        raise error(yaml_problem_text(path, what, problem)) from None


def read_yaml(path: str | os.PathLike[str], what: str,
              error: type[Exception] = ValueError) -> Any:
    """A YAML file's content (see :func:`read_yaml_lines`)."""
    return read_yaml_lines(path, what, error)[0]
