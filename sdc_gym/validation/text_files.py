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
