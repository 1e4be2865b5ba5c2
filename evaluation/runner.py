"""Run many episodes and collect their results, in this process or in worker processes.

:func:`run_episodes` hands the specs to a *backend* and shows a rich progress bar counting
laps (with a line per running episode that moves during the episode, useful for a single
long endurance run). A backend is anything with ``run(specs, events)`` that runs every
spec somewhere and tells ``events`` (:class:`EpisodeEvents`) when an episode starts,
advances, finishes, or fails (it raised, or the process running it died): a failed
episode is reported with its reason and the others still run.

* :class:`InProcessBackend`: one after the other in this process;
* :class:`ProcessPoolBackend`: a local pool of worker processes
  (:class:`concurrent.futures.ProcessPoolExecutor`), each pinned to one math thread, each
  ending itself when the process that made the pool dies (even by ``kill -9``);
* :class:`sdc_evaluation.ray_backend.RayBackend`: Ray tasks on a cluster (``--ray``).

Nothing else in the evaluation depends on where episodes run.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
import traceback
from collections.abc import Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from queue import Empty
from typing import Any, Protocol

from sdc_evaluation.episodes import EpisodeSpec, run_episode
from sdc_gym.bridge.reaper import prctl
from sdc_gym.units import METERS_PER_MILE


class EpisodeEvents(Protocol):
    """What a backend reports while it runs the specs (indices into the spec list)."""

    def started(self, index: int) -> None: ...

    def progress(self, index: int, laps: float, fields: dict[str, float]) -> None: ...

    def finished(self, index: int, result: dict[str, Any]) -> None: ...

    def failed(self, index: int, reason: str, details: str) -> None:
        """The episode ended without a result: ``reason`` in one line (the exception's
        type and message, or how its worker died), ``details`` its traceback."""


class EpisodeBackend(Protocol):
    """Runs every spec once and reports through ``events``; returns when all are done.

    Every spec ends in exactly one ``finished`` or ``failed``: an episode that raises (an
    ``Exception``), or whose worker process dies, is reported as failed and the other
    episodes still run. ``KeyboardInterrupt`` (and other ``BaseException``) stops the run:
    the backend cancels what is still running and lets it propagate.
    """

    def run(self, specs: Sequence[EpisodeSpec], events: EpisodeEvents) -> None: ...


@dataclass(frozen=True)
class EpisodeFailure:
    """An episode that ended without a result (see :class:`EpisodeBackend`)."""

    agent: str
    seed: int
    reason: str
    details: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"agent": self.agent, "seed": self.seed, "reason": self.reason,
                "details": self.details}


@dataclass(frozen=True)
class EpisodeRuns:
    """What :func:`run_episodes` returns: the results of the episodes that finished, in
    the specs' order, and those that failed."""

    results: list[dict[str, Any]]
    failures: list[EpisodeFailure]


def failure_reason(error: BaseException) -> str:
    """One line for an episode's exception: ``"ValueError: no model file at x.zip"``."""
    message = str(error).strip().splitlines()
    return f"{type(error).__name__}: {message[0]}" if message else type(error).__name__


def failure_details(error: BaseException) -> str:
    """The exception's traceback (a worker's own traceback included, as the pool and Ray
    attach it), for ``summary.json``."""
    return "".join(traceback.format_exception(error)).rstrip()


def progress_fields(info: dict[str, Any]) -> dict[str, float]:
    """The few numbers of a running episode that the progress line shows."""
    return {"distance": float(info["distance"]),
            "clean": float(info["distance_without_incident"]),
            "incidents": float(info["incidents"])}


class InProcessBackend:
    """Every episode in this process, one after the other (``--workers 1``)."""

    def run(self, specs: Sequence[EpisodeSpec], events: EpisodeEvents) -> None:
        for index, spec in enumerate(specs):
            events.started(index)

            def report(laps: float, info: dict[str, Any], index: int = index) -> None:
                events.progress(index, laps, progress_fields(info))

            try:
                result = run_episode(spec, report)
            except Exception as error:  # reported; the other episodes still run
                events.failed(index, failure_reason(error), failure_details(error))
            else:
                events.finished(index, result)


WORKER_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
"""Thread counts pinned to 1 in worker processes (unless set): the workers already fill the
cores, and a torch model (the light classifiers) using every core in every worker ran
~10 x slower than single-threaded."""

_WORKER_QUEUE: Any = None  # a worker process's progress queue, set by _init_worker
PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
PARENT_POLL_S = 0.5  # how often a worker checks that its parent is still there


def _init_worker(queue: Any, owner: int) -> None:
    global _WORKER_QUEUE  # per-process state of the pool's workers
    _WORKER_QUEUE = queue
    for variable in WORKER_THREAD_VARIABLES:  # read by torch when a worker imports it
        os.environ.setdefault(variable, "1")
    _die_with_parent(owner)


def _die_with_parent(owner: int) -> None:
    """End this worker when its parent dies, even by ``kill -9``, which leaves the pool
    no chance to stop its workers. The parent is ``owner``, the process that made the
    pool (or, with the forkserver start method, the fork server, which ends with it).

    Linux: the kernel sends SIGKILL when the parent exits (``PR_SET_PDEATHSIG``). Elsewhere,
    and as a fallback, a daemon thread sees the parent process id change (the worker was
    re-parented) and exits. A worker's planner (``external:``) is then ended by its own
    watchdog (:mod:`sdc_gym.bridge.reaper`).
    """
    parent = os.getppid()
    prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    try:
        os.kill(owner, 0)
    except ProcessLookupError:  # it died before the flag was set
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="parent watchdog", daemon=True).start()


def _run_in_worker(index: int, spec: EpisodeSpec) -> dict[str, Any]:
    queue = _WORKER_QUEUE

    def report(laps: float, info: dict[str, Any]) -> None:
        queue.put((index, laps, progress_fields(info)))

    return run_episode(spec, report)


class ProcessPoolBackend:
    """Episodes in ``workers`` local processes; progress comes back through a queue.

    ``poll_s`` is how often the parent looks at the queue and the finished episodes.
    """

    def __init__(self, workers: int, poll_s: float = 0.2) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.workers = workers
        self.poll_s = poll_s

    def run(self, specs: Sequence[EpisodeSpec], events: EpisodeEvents) -> None:
        if not specs:
            return
        context = multiprocessing.get_context()
        queue = context.Queue()
        done_indices: set[int] = set()

        def drain() -> None:
            while True:
                try:
                    index, laps, fields = queue.get_nowait()
                except Empty:
                    return
                if index not in done_indices:
                    events.progress(index, laps, fields)

        try:
            with ProcessPoolExecutor(max_workers=min(self.workers, len(specs)),
                                     mp_context=context, initializer=_init_worker,
                                     initargs=(queue, os.getpid())) as pool:
                futures = {pool.submit(_run_in_worker, i, spec): i
                           for i, spec in enumerate(specs)}
                pending = set(futures)
                try:
                    while pending:
                        done, pending = wait(pending, timeout=self.poll_s,
                                             return_when=FIRST_COMPLETED)
                        drain()
                        for future in done:
                            index = futures[future]
                            done_indices.add(index)
                            error = future.exception()
                            if error is None:
                                events.finished(index, future.result())
                            else:  # raised in the worker, or the worker died
                                events.failed(index, failure_reason(error),
                                              failure_details(error))
                except BaseException:
                    pool.shutdown(wait=False, cancel_futures=True)
                    raise
        finally:
            queue.close()


def default_backend(workers: int, episodes: int) -> EpisodeBackend:
    """In this process for one worker or one episode, else a local process pool."""
    return InProcessBackend() if workers <= 1 or episodes <= 1 else ProcessPoolBackend(workers)


class _ProgressDisplay:
    """A rich progress bar: laps of all episodes, plus one line per running episode.

    It is the runner's :class:`EpisodeEvents`: it also collects the results.
    """

    def __init__(self, specs: Sequence[EpisodeSpec], enabled: bool) -> None:
        from rich.progress import (
            BarColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.specs = specs
        self.results: list[dict[str, Any] | None] = [None] * len(specs)
        self.failures: dict[int, EpisodeFailure] = {}
        self.laps = [float(spec.env_config.get("laps", 1)) for spec in specs]
        self.done = [0.0] * len(specs)
        self.finished_count = 0
        self.bar = Progress(
            TextColumn("{task.description}"), BarColumn(bar_width=20),
            TextColumn("{task.completed:.1f}/{task.total:g} laps"), TimeElapsedColumn(),
            TimeRemainingColumn(), TextColumn("{task.fields[status]}"),
            disable=not enabled, transient=True)
        self.total = self.bar.add_task(self._overall(), total=sum(self.laps), status="")
        self.tasks: dict[int, Any] = {}

    def _overall(self) -> str:
        return f"episodes {self.finished_count}/{len(self.specs)}"

    def __enter__(self) -> _ProgressDisplay:
        self.bar.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.bar.__exit__(*exc)

    def started(self, index: int) -> None:
        if index not in self.tasks:
            spec = self.specs[index]
            self.tasks[index] = self.bar.add_task(
                f"  {spec.agent_name} seed {spec.seed}", total=self.laps[index], status="")

    def progress(self, index: int, laps: float, fields: dict[str, float]) -> None:
        self.started(index)
        laps = min(laps, self.laps[index])
        status = (f"{fields['distance'] / METERS_PER_MILE:.1f} mi, "
                  f"{fields['clean'] / METERS_PER_MILE:.1f} without incident, "
                  f"{fields['incidents']:.0f} incidents")
        self.bar.update(self.tasks[index], completed=laps, status=status)
        self._set(index, laps)

    def finished(self, index: int, result: dict[str, Any]) -> None:
        self.results[index] = result
        self._end(index)

    def failed(self, index: int, reason: str, details: str) -> None:
        spec = self.specs[index]
        self.failures[index] = EpisodeFailure(spec.agent_name, spec.seed, reason, details)
        if not self.bar.disable:  # above the live bar, as it happens (the caller reports)
            self.bar.console.print(f"{spec.agent_name} seed {spec.seed} failed: {reason}",
                                   markup=False, highlight=False)
        self._end(index)

    def _end(self, index: int) -> None:
        if index in self.tasks:
            self.bar.remove_task(self.tasks.pop(index))
        self.finished_count += 1
        self._set(index, self.laps[index])

    def _set(self, index: int, laps: float) -> None:
        self.done[index] = laps
        self.bar.update(self.total, completed=sum(self.done), description=self._overall())


def run_episodes(specs: Sequence[EpisodeSpec], workers: int = 1, progress: bool = True,
                 backend: EpisodeBackend | None = None) -> EpisodeRuns:
    """Run every spec: the results in the specs' order, and the episodes that failed.

    ``backend`` defaults to :func:`default_backend` for ``workers``. ``progress`` shows a
    rich bar counting laps, with a line per running episode (and a line per failure).
    """
    backend = backend or default_backend(workers, len(specs))
    with _ProgressDisplay(specs, progress) as display:
        backend.run(specs, display)
    missing = [f"{specs[i].agent_name} seed {specs[i].seed}"
               for i, result in enumerate(display.results)
               if result is None and i not in display.failures]
    if missing:
        raise RuntimeError(f"the backend returned without a result or a failure for "
                           f"{missing}")
    return EpisodeRuns([result for result in display.results if result is not None],
                       [display.failures[i] for i in sorted(display.failures)])
