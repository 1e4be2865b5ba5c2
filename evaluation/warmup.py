"""Compile the kernels once in the parent before episodes fan out to worker processes.

numba compiles a kernel the first time it runs and caches the machine code on disk; with
an empty cache, every worker of a process pool would compile the same kernels at once
(the default ``evaluate.py`` spent 30 s so, both workers compiling). :func:`warm_up`
drives each distinct agent and env of a run for a second of simulated time in this
process, under :func:`sdc_gym.kernel_compiler.compile_progress`, so that the workers find
a full cache and the user sees what the first run is doing. With a full cache it costs a
fraction of a second per agent.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

from sdc_evaluation.episodes import EpisodeSpec, run_episode
from sdc_gym.kernel_compiler import compile_progress

WARM_UP_SECONDS = 1.0
"""Simulated seconds each distinct agent drives while warming up."""


def _is_built_in(agent: str) -> bool:
    """Agents run in this process (not an external program that would be started)."""
    return agent.split(":", 1)[0] not in {"external", "capstone"}


def warm_up(specs: Sequence[EpisodeSpec], console: Any = None) -> int:
    """Run a short episode of each distinct built-in agent and env of ``specs``; returns
    how many kernels were compiled. An agent that fails here is left to fail in its real
    episodes, where the failure is reported."""
    seen: set[tuple[str, str]] = set()
    with compile_progress(console) as counter:
        for spec in specs:
            key = (spec.agent, spec.env_id)
            if key in seen or not _is_built_in(spec.agent):
                continue
            seen.add(key)
            short = dataclasses.replace(
                spec, env_config={**spec.env_config, "max_duration": WARM_UP_SECONDS},
                trace_points=0, incident_history=0.0)
            try:
                run_episode(short)
            except Exception:
                continue
        return counter.count
