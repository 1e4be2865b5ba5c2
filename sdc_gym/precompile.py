"""Compile every env's kernels ahead of the first use: ``python -m sdc_gym.precompile``.

    python -m sdc_gym.precompile [--workers 2] [--envs sdc_gym/TrackLoop-v0 ...]

numba compiles a kernel the first time it runs and caches the machine code in
``__pycache__`` (:mod:`sdc_gym.kernel_compiler`); on a fresh clone the first step of each
env compiles 15-31 functions (17-36 s of CPU). This command pays that once, at set-up
(``make`` runs it after installing), so that a user's first env step loads the cache.

Each *family* of envs (the highway envs share most kernels, the track envs theirs) is
made, reset and stepped once, in order, in its own worker process: the kernels a family
shares compile once, and the families compile in parallel, one per core. A rich progress
line (or plain lines in a log) counts the envs done; the summary gives each env's
kernels compiled and CPU seconds. With a full cache it takes a few seconds.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import resource
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from typing import Any

FAMILIES: tuple[tuple[str, ...], ...] = (
    ("sdc_gym/HighwayLoop-v0", "sdc_gym/HighwayLoopBehavior-v0"),
    ("sdc_gym/TrackLoop-v0", "sdc_gym/TrackLoopBehavior-v0"),
)
"""The env ids precompiled by default, grouped by the kernels they share."""


@dataclass(frozen=True)
class Compiled:
    """One env's first use in a precompile worker."""

    env_id: str
    kernels: int
    """This package's functions numba compiled (0: all loaded from the cache)."""
    cpu_seconds: float
    """CPU (user + sys) of the worker during make, reset and the first step."""


def _cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def first_use(env_id: str) -> Compiled:
    """Make, reset and step ``env_id`` once in this process, counting the compilations."""
    import gymnasium as gym
    import numpy as np
    from numba.core import event

    import sdc_gym  # noqa: F401  (registers the envs)
    from sdc_gym.kernel_compiler import _CompileCounter

    counter = _CompileCounter(lambda name, count: None)
    event.register("numba:compile", counter)
    started = _cpu()
    try:
        env = gym.make(env_id)
        env.reset(seed=0)
        space = env.action_space
        action = (np.zeros(space.shape, dtype=space.dtype)
                  if isinstance(space, gym.spaces.Box) else space.sample())
        env.step(action)
        env.close()
    finally:
        event.unregister("numba:compile", counter)
    return Compiled(env_id, counter.count, _cpu() - started)


def _family(env_ids: Sequence[str]) -> list[Compiled]:
    """A worker's job: the first use of each env of one family, in order."""
    os.environ.setdefault("SDC_GYM_COMPILE_NOTICE", "0")  # the parent shows progress
    return [first_use(env_id) for env_id in env_ids]


def precompile(families: Sequence[Sequence[str]] = FAMILIES, workers: int | None = None,
               console: Any = None) -> list[Compiled]:
    """Run each family's first use in a fresh worker process (``workers`` at once, default
    one per core up to the number of families), showing progress on ``console`` (rich,
    stderr by default); returns every env's :class:`Compiled`, in the order given."""
    from rich.console import Console

    console = console if console is not None else Console(stderr=True)
    families = [tuple(family) for family in families if family]
    workers = workers or min(len(families), os.cpu_count() or 1)
    total = sum(len(family) for family in families)
    results: dict[str, Compiled] = {}
    started = time.perf_counter()
    status = console.status(f"precompiling sdc-gym's kernels: 0 of {total} envs") \
        if console.is_terminal else None
    if status is not None:
        status.start()
    else:
        console.print(f"precompiling sdc-gym's kernels for {total} envs "
                      f"({workers} processes) ...", highlight=False)
    # spawn: a fresh interpreter per worker, nothing of this process's numba state shared.
    context = multiprocessing.get_context("spawn")
    try:
        with ProcessPoolExecutor(max_workers=workers, mp_context=context) as pool:
            futures = [pool.submit(_family, family) for family in families]
            for future in as_completed(futures):
                for done in future.result():
                    results[done.env_id] = done
                    line = (f"{done.env_id}: {done.kernels} kernels compiled, "
                            f"{done.cpu_seconds:.1f} s CPU")
                    if status is not None:
                        status.update(f"precompiling sdc-gym's kernels: {len(results)} of "
                                      f"{total} envs ({time.perf_counter() - started:.0f} s)")
                    console.print(line, highlight=False)
    finally:
        if status is not None:
            status.stop()
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    console.print(f"precompiled {sum(r.kernels for r in results.values())} kernels in "
                  f"{time.perf_counter() - started:.0f} s wall, "
                  f"{children.ru_utime + children.ru_stime:.0f} s CPU of the workers "
                  "(cached in __pycache__ for later runs)", highlight=False)
    return [results[env_id] for family in families for env_id in family]


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=None,
                        help="processes at once (default: one per core, at most 2)")
    parser.add_argument("--envs", nargs="+", default=None,
                        help="env ids, each in its own family (default: all four envs)")
    args = parser.parse_args(argv)
    if args.workers is not None and args.workers < 1:
        parser.error(f"--workers {args.workers}: a number of processes, 1 or more")
    families = [(env_id,) for env_id in args.envs] if args.envs else FAMILIES
    precompile(families, workers=args.workers)


if __name__ == "__main__":
    main()
