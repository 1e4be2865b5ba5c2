"""Text files read by sdc-gym (maps, tracks, light configs, YAML configs): UTF-8 of bounded
size, or a clear error.

The original data files are ASCII. A file that is not UTF-8 (binary data, or another
encoding such as latin-1) is refused with the file, the byte offset and a hint, instead of
the ``UnicodeDecodeError`` the audit saw; so is a file larger than :data:`MAX_TEXT_BYTES`
(the original files are under 1 MB; a bigger one is a wrong path or data that would take
minutes and gigabytes to build a road from).

YAML is read as YAML 1.2 reads numbers: ``1e-4`` is a float (PyYAML's YAML 1.1 resolver
makes it the string ``"1e-4"``, which a learning rate then rejects far from the cause).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Final

import yaml

MAX_TEXT_BYTES: Final = 64 * 1024 * 1024
"""The largest map, track, light or config file read (64 MiB)."""


def read_text(path: str | os.PathLike[str], what: str, error: type[Exception] = ValueError,
              max_bytes: int = MAX_TEXT_BYTES) -> str:
    """The file's text, decoded as UTF-8 (a BOM is dropped); ``error`` (naming ``what``
    file, the path and the problem) for a missing, huge, binary or non-UTF-8 file."""
    path = Path(path)
    if not path.is_file():
        raise error(f"{what} not found: {path}")
    size = path.stat().st_size
    if size > max_bytes:
        raise error(f"{path}: the {what} is {size:,} bytes; at most {max_bytes:,} are read "
                    "(is this the right file?)")
    data = path.read_bytes()
    if b"\x00" in data:
        offset = data.index(b"\x00")
        raise error(f"{path}: the {what} is binary, not text (a NUL byte at offset "
                    f"{offset}); expected UTF-8 text")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as decode:
        line = data[:decode.start].count(b"\n") + 1
        raise error(f"{path}:{line}: the {what} is not UTF-8 text (byte 0x{data[decode.start]:02x}"
                    f" at offset {decode.start}; a latin-1 or other encoding? save it as "
                    "UTF-8)") from None


class _Yaml12Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2's floats (``1e-4``, ``1E5`` without a dot)."""


_Yaml12Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                  |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                  |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                  |[-+]?\.(?:inf|Inf|INF)
                  |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def parse_yaml(text: str) -> Any:
    """YAML text to Python values (safe: no Python objects), with YAML 1.2's floats."""
    return yaml.load(text, Loader=_Yaml12Loader)  # a SafeLoader: data only


def read_yaml(path: str | os.PathLike[str], what: str,
              error: type[Exception] = ValueError) -> Any:
    """A YAML file's content (see :func:`read_text`); ``error`` for invalid YAML."""
    text = read_text(path, what, error)
    try:
        return parse_yaml(text)
    except yaml.YAMLError as problem:
        raise error(f"{path}: the {what} is not valid YAML ({problem})") from None


def parse_yaml_lines(text: str) -> tuple[Any, dict[str, int]]:
    """YAML text to Python values (as :func:`parse_yaml`) and the line (1-based) of every
    key and list item, by key path (``"cars[2].speed"``; ``""`` is the document), read
    from PyYAML's node tree so that errors can name the line."""
    loader = _Yaml12Loader(text)
    try:
        node = loader.get_single_node()
        data = loader.construct_document(node) if node is not None else None
    finally:
        loader.dispose()
    lines: dict[str, int] = {}
    if node is not None:
        _node_lines(node, "", lines)
    return data, lines


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


def read_yaml_lines(path: str | os.PathLike[str], what: str,
                    error: type[Exception] = ValueError) -> tuple[Any, dict[str, int]]:
    """A YAML file's content and its lines by key path (see :func:`parse_yaml_lines`);
    ``error`` (naming the file and line) for an unreadable file or invalid YAML."""
    text = read_text(path, what, error)
    try:
        return parse_yaml_lines(text)
    except yaml.YAMLError as problem:
        mark = getattr(problem, "problem_mark", None)
        where = f"{path}:{mark.line + 1}" if mark is not None else f"{path}"
        raise error(f"{where}: the {what} is not valid YAML ({problem})") from None
