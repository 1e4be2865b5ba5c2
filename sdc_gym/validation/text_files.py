"""Text files read by sdc-gym (maps, tracks, light configs, YAML configs): UTF-8 of bounded
size, or a clear error (YAML is then parsed by :mod:`sdc_gym.validation.yaml_files`).

The original data files are ASCII. A file that is not UTF-8 (binary data, or another
encoding such as latin-1) is refused with the file, the byte offset and a hint, instead of
the ``UnicodeDecodeError`` the audit saw; so is a file larger than :data:`MAX_TEXT_BYTES`
(the original files are under 400 kB; a bigger one is a wrong path or data that would take
minutes and gigabytes to build a road from).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Final

from sdc_gym.config import excerpt
from sdc_gym.validation.bounds import MAX_PATH_CHARS

MAX_TEXT_BYTES: Final = 2 * 1024 * 1024
"""The largest map, track or light file read (2 MiB: 7 x the largest original file, the
capstone's 335 kB ``wp_yaw_const.csv``; a 2.8 MB track loads in 5.5 s on the loaded 2-core
machine, a 58 MB map took 73 s). YAML files have their own, smaller bound
(:data:`sdc_gym.validation.yaml_files.MAX_YAML_BYTES`)."""


def check_path_text(path: str | os.PathLike[str], what: str,
                    error: type[Exception] = ValueError) -> None:
    """``error`` for a path longer than :data:`~sdc_gym.validation.bounds.MAX_PATH_CHARS`
    (``{"map": "x" * 100000}`` was an OSError "File name too long")."""
    text = os.fspath(path)
    if len(text) > MAX_PATH_CHARS:
        raise error(f"the {what} path is {len(text):,} characters ({excerpt(text)}); at most "
                    f"{MAX_PATH_CHARS:,} (a file path)")


def read_text(path: str | os.PathLike[str], what: str, error: type[Exception] = ValueError,
              max_bytes: int = MAX_TEXT_BYTES) -> str:
    """The file's text, decoded as UTF-8 (a BOM is dropped); ``error`` (naming ``what``
    file, the path and the problem) for a missing, huge, binary or non-UTF-8 file."""
    check_path_text(path, what, error)
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
