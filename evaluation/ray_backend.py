"""Episodes as Ray tasks: the same evaluation on a cluster (``evaluate.py --ray``).

:class:`RayBackend` is a backend of :mod:`sdc_evaluation.runner`: every spec becomes one Ray
task (one CPU, the math libraries pinned to one thread as in the local pool) that runs
:func:`sdc_evaluation.episodes.run_episode` where the cluster has room, on this machine or on
any node. An episode is a function of its spec (seeded env, deterministic agents), so the
results are those of the local pool, row for row; only the wall times differ.

Progress comes back through a :class:`ray.util.queue.Queue` (an actor) that the tasks put
their lap counts in; the driver polls it and the finished tasks every ``poll_s``. A task
that raises is reported with the exception's type, message and remote traceback; a task
whose worker process dies (killed, out of memory, its node lost) with Ray's reason; the
other tasks still run. Tasks are not retried by default (``retries``): an episode that
kills its worker would kill the next one too, and a failure should be seen.

The cluster is :func:`sdc_gym.ray.ray_session`'s: a running one (``"auto"``, an address;
each node needs the project installed at the same path, with the same Python) or a local
one started for the run and shut down when it ends, also on Ctrl-C. Result files are
written by the driver, as for every backend.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from typing import Any

from sdc_evaluation.episodes import EpisodeSpec, ProgressCallback, run_episode
from sdc_evaluation.runner import (
    WORKER_THREAD_VARIABLES,
    EpisodeEvents,
    failure_details,
    failure_reason,
    progress_fields,
)
from sdc_gym.ray import LOCAL, ray_session

EpisodeFunction = Callable[[EpisodeSpec, ProgressCallback], dict[str, Any]]
"""``episode(spec, progress) -> result``: :func:`run_episode` (tests inject faults here)."""

ANSI_ESCAPES = re.compile(r"\x1b\[[0-9;]*m")
"""Ray colours the task's name in its error text; the details are plain text."""
STARTED = "started"
PROGRESS = "progress"


def _episode_task(index: int, spec: EpisodeSpec, queue: Any,
                  episode: EpisodeFunction) -> dict[str, Any]:
    """Runs in a Ray worker: one episode, its progress put in ``queue``."""

    def report(laps: float, info: dict[str, Any]) -> None:
        queue.put_nowait((PROGRESS, index, laps, progress_fields(info)))

    queue.put_nowait((STARTED, index, 0.0, {}))
    return episode(spec, report)


class RayBackend:
    """Every episode as a Ray task on the cluster at ``address`` (see the module doc).

    ``address``: :data:`sdc_gym.ray.LOCAL` (a local cluster of ``num_cpus`` cores,
    default all, for the run), ``"auto"`` or ``"HOST:PORT"`` (a running cluster).
    ``episode`` runs one spec (default :func:`run_episode`); ``retries`` is Ray's
    ``max_retries`` for a task whose worker died.
    """

    def __init__(self, address: str = LOCAL, num_cpus: int | None = None,
                 poll_s: float = 0.2, episode: EpisodeFunction = run_episode,
                 retries: int = 0) -> None:
        if num_cpus is not None and num_cpus < 1:
            raise ValueError(f"num_cpus must be >= 1, got {num_cpus}")
        if retries < 0:
            raise ValueError(f"retries must be >= 0, got {retries}")
        self.address = address
        self.num_cpus = num_cpus
        self.poll_s = poll_s
        self.episode = episode
        self.retries = retries

    def run(self, specs: Sequence[EpisodeSpec], events: EpisodeEvents) -> None:
        if not specs:
            return
        import ray
        from ray.util.queue import Queue

        with ray_session(self.address, self.num_cpus):
            queue = Queue(actor_options={"num_cpus": 0})
            task = ray.remote(_episode_task).options(
                num_cpus=1, max_retries=self.retries, retry_exceptions=False,
                runtime_env={"env_vars": {variable: os.environ.get(variable, "1")
                                          for variable in WORKER_THREAD_VARIABLES}})
            episode = ray.put(self.episode)
            pending = {task.remote(index, spec, queue, episode): index
                       for index, spec in enumerate(specs)}
            done: set[int] = set()
            try:
                while pending:
                    ready, _ = ray.wait(list(pending), num_returns=len(pending),
                                        timeout=self.poll_s)
                    self._drain(queue, events, done)
                    for ref in ready:
                        index = pending.pop(ref)
                        done.add(index)
                        self._report(ref, index, events)
            except BaseException:
                for ref in pending:  # a running cluster goes on: stop this run's tasks
                    ray.cancel(ref, force=True)
                raise
            finally:
                ray.kill(queue.actor)

    @staticmethod
    def _drain(queue: Any, events: EpisodeEvents, done: set[int]) -> None:
        count = queue.qsize()
        for kind, index, laps, fields in (queue.get_nowait_batch(count) if count else ()):
            if index in done:
                continue
            if kind == STARTED:
                events.started(index)
            else:
                events.progress(index, laps, fields)

    @staticmethod
    def _report(ref: Any, index: int, events: EpisodeEvents) -> None:
        import ray
        from ray.exceptions import RayTaskError

        try:
            result = ray.get(ref)
        except RayTaskError as error:  # the episode raised: its own exception and traceback
            cause = error.cause if isinstance(error.cause, BaseException) else error
            # Ray's text: the task, its pid and node, and the worker's traceback.
            events.failed(index, failure_reason(cause), ANSI_ESCAPES.sub("", str(error)))
        except ray.exceptions.RayError as error:  # the worker (or its node) died
            events.failed(index, f"the worker died: {failure_reason(error)}",
                          failure_details(error))
        else:
            events.finished(index, result)
