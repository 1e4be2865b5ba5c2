"""Fault-injecting episode functions for the Ray backend's tests (imported by the Ray
workers, so they live in a module of their own, not in a test file)."""

from __future__ import annotations

import os
from typing import Any

from evaluation.episodes import EpisodeSpec, ProgressCallback, run_episode

DIES_ON_SEED = 1
"""The seed whose worker process exits in the middle of its episode."""


def die_on_seed(spec: EpisodeSpec, progress: ProgressCallback) -> dict[str, Any]:
    """:func:`run_episode`, except that the worker of seed :data:`DIES_ON_SEED` exits
    (``os._exit``: no exception, no clean-up, as a killed process) after its first
    progress report."""
    if spec.seed != DIES_ON_SEED:
        return run_episode(spec, progress)

    def report_then_die(laps: float, info: dict[str, Any]) -> None:
        progress(laps, info)
        os._exit(3)

    return run_episode(spec, report_then_die)
