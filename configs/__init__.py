"""The project's YAML configs, installed as package data (``sdc_configs``).

This folder is the source: env configs (``highway_dense_traffic.yaml``, ``track_loop.yaml``
...: ``evaluate.py --config``), run configs (``train_highway_behavior.yaml``:
``train.py --config``), hyperparameters by algorithm and env id (``hyperparams/``) and Ray
Tune sweeps (``tune/``). The wheel ships them as the package ``sdc_configs`` (pyproject's
package-dir), so that ``sdc-train --config train_highway_behavior`` finds them from any
folder; in a checkout the editable install maps the same name onto this folder.

:func:`config_path` is how the scripts resolve a ``--config`` / ``--tune`` argument.
"""

from __future__ import annotations

import argparse
from importlib import resources
from pathlib import Path

SUFFIX = ".yaml"


def packaged(relative: str | Path = "") -> Path:
    """The packaged file or folder ``relative`` (``"hyperparams"``, ``"tune/highway_ppo.yaml"``)
    as a path on disk (a wheel installs as files, an editable install is this folder)."""
    return Path(str(resources.files(__name__).joinpath(str(relative))))


def packaged_names() -> list[str]:
    """The packaged configs as ``config_path`` accepts them (``"track_loop"``,
    ``"tune/highway_ppo"``)."""
    root = packaged()
    return sorted(path.relative_to(root).with_suffix("").as_posix()
                  for path in root.rglob(f"*{SUFFIX}"))


def config_path(text: str) -> Path:
    """A ``--config`` or ``--tune`` argument as a file: the path as given when it exists,
    else the packaged config it names: ``configs/track_loop.yaml`` (the checkout's path,
    also from another folder), ``track_loop.yaml`` or ``track_loop``
    (``tune/highway_ppo`` for a sweep). ``argparse.ArgumentTypeError`` naming the value
    and the packaged configs when it is neither."""
    given = Path(text)
    if given.is_file() or given.is_absolute():
        return given
    parts = given.parts[1:] if given.parts[:1] == ("configs",) else given.parts
    if parts:
        candidate = packaged(Path(*parts).with_suffix(SUFFIX))
        if candidate.is_file():
            return candidate
    raise argparse.ArgumentTypeError(
        f"{text!r}: no such file, nor a packaged config; packaged: "
        f"{', '.join(packaged_names())}")
