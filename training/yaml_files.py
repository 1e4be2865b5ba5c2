"""YAML files of mappings (run configs, sweep files), read with clear errors."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml


def read_yaml(path: Path, label: str = "") -> dict[str, Any]:
    """The mapping in the YAML file at ``path`` ({} for an empty file); ``SystemExit``
    naming the file (after ``label``, e.g. ``"--tune "``) when it is missing, not YAML or
    not a mapping."""
    where = f"{label}{path}"
    if not path.is_file():
        raise SystemExit(f"{where}: no such file")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except yaml.YAMLError as error:
        raise SystemExit(f"{where}: not valid YAML: {error}") from None
    if not isinstance(data, dict):
        raise SystemExit(f"{where}: expected a mapping")
    return data
