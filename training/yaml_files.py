"""YAML files of mappings (run configs, hyperparameter and sweep files), read with clear
errors: UTF-8 of bounded size and YAML 1.2 numbers, as every sdc-gym file
(:mod:`sdc_gym.validation.yaml_files`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sdc_gym.validation.yaml_files import read_yaml as read_yaml_file


def read_yaml(path: Path, what: str = "YAML file") -> dict[str, Any]:
    """The mapping in the YAML file at ``path`` ({} for an empty file); ``SystemExit``
    naming ``what`` file and the path when it is missing, not text, not YAML or not a
    mapping."""
    data = read_yaml_file(path, what, SystemExit) or {}
    if not isinstance(data, dict):
        raise SystemExit(f"{path}: expected a mapping, got {type(data).__name__}")
    return data
