"""One batched env split over worker processes: both cores for one batch, bit for bit.

``gym.make_vec(id, num_envs=E, vectorization_mode="vector_entry_point", processes=2)``
returns :class:`SplitVectorEnv`: the ``E`` envs in ``processes`` contiguous blocks (envs
``0..E/2-1`` and ``E/2..E-1`` for two), each block a native batch of the same id in a worker
process of its own, stepped at the same time. Everything a step does runs in the workers,
the Python between the kernels too, so the split scales where ``kernel_threads`` (numba's
threads inside one process, ``docs/batched.md``) is held back by that serial part.

Env ``i`` is exactly env ``i`` of the one-process batch: the batch's envs are independent
(env ``i`` of a batch is the single env with its seed), ``reset(seed=s)`` gives block ``b``
starting at env ``k`` the seed ``s + k``, and every array the blocks return is put back in
env order, ``info`` by the vector API's masks. The parent checks what can be checked for
the whole batch (the seeds, the reset options, the number of actions); an error a block
raises (an action out of range) comes back as the same exception, naming the block.

Each worker is a fresh ``python -m sdc_gym.envs.split_worker`` process
(:mod:`~sdc_gym.envs.split_worker`: no fork of a process that may hold torch's or numba's
threads, no re-run of the owner's script) and ends with its owner: on :meth:`close`,
when the owner's end of the connection closes, and by ``PR_SET_PDEATHSIG`` when the owner
is killed. A worker pays its own import and kernel load when it starts (about 2 s of CPU
on a warm numba cache; on an empty one the workers compile the kernels, each its own).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium.envs.registration import registry
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from sdc_gym.config import excerpt
from sdc_gym.envs.split_worker import WorkerError
from sdc_gym.scenarios.options import (
    OPTION,
    RESET_MASK,
    batch_scenarios,
    check_reset_options,
    reset_mask,
)
from sdc_gym.validation.bounds import check_env_count


def check_processes(processes: Any, num_envs: int) -> int:
    """``processes`` as an int in ``1..num_envs``, or a ``ValueError`` naming it."""
    if (not isinstance(processes, int | np.integer) or isinstance(processes, bool | np.bool_)
            or not 1 <= processes <= num_envs):
        raise ValueError(f"processes must be an int in [1, num_envs = {num_envs}] (1 steps the "
                         f"batch in this process; 2 splits it over both cores), got "
                         f"{excerpt(processes)}")
    return int(processes)


def worker_environment() -> dict[str, str]:
    """This process's environment, with the folder this ``sdc_gym`` was imported from first
    on ``PYTHONPATH``: a worker imports the same package even when it is not installed
    (a script that put the checkout on ``sys.path`` itself)."""
    environment = dict(os.environ)
    home = str(Path(__file__).resolve().parents[2])
    environment["PYTHONPATH"] = os.pathsep.join(
        [home, *filter(None, environment.get("PYTHONPATH", "").split(os.pathsep))])
    return environment


def block_bounds(num_envs: int, processes: int) -> list[tuple[int, int]]:
    """The ``[start, stop)`` env ranges of the blocks: contiguous, sizes differing by at most
    one (the first blocks the larger)."""
    size, extra = divmod(num_envs, processes)
    bounds, start = [], 0
    for block in range(processes):
        stop = start + size + (block < extra)
        bounds.append((start, stop))
        start = stop
    return bounds


def merge_infos(parts: list[dict[str, Any]], bounds: list[tuple[int, int]],
                num_envs: int) -> dict[str, Any]:
    """The blocks' vector ``info`` dicts as the one-process batch's: each key's array over
    all envs, the blocks' values at their envs, and where a block has no such key the
    value Gymnasium's ``_add_info`` leaves for an env without it (0 of the array's dtype,
    ``None`` in an object array, ``False`` in a mask); nested dicts key by key. Keys come
    in the order the envs first gave them, as ``_add_info`` adds them."""
    merged: dict[str, Any] = {}
    for part in parts:
        for key, value in part.items():
            if key in merged:
                continue
            if isinstance(value, dict):
                merged[key] = merge_infos([item.get(key, {}) for item in parts], bounds, num_envs)
                continue
            array = (np.full((num_envs, *value.shape[1:]), None, dtype=object)
                     if value.dtype == object else
                     np.zeros((num_envs, *value.shape[1:]), dtype=value.dtype))
            for item, (start, stop) in zip(parts, bounds, strict=True):
                if key in item:
                    array[start:stop] = item[key]
            merged[key] = array
    return merged


def _concatenate(parts: list[Any]) -> Any:
    """The blocks' batched arrays (or dicts of them, the path-level env's observations) in
    env order."""
    if isinstance(parts[0], dict):
        return {key: _concatenate([part[key] for part in parts]) for key in parts[0]}
    return np.concatenate(parts)


class SplitVectorEnv(VectorEnv):
    """``num_envs`` envs of ``env_id`` as ``processes`` native batches in worker processes
    (see the module docstring). ``kwargs`` go to each block's vector entry point (``config``,
    ``autoreset_mode``, ``full_info``)."""

    def __init__(self, env_id: str, entry_point: str, num_envs: int, processes: int,
                 **kwargs: Any) -> None:
        self.processes = check_processes(processes, num_envs)
        self.num_envs = num_envs
        self.env_id = env_id
        self.bounds = block_bounds(num_envs, self.processes)
        self._closed = False
        self._connections: list[Connection] = []
        self._workers: list[subprocess.Popen[bytes]] = []
        environment = worker_environment()
        for start, stop in self.bounds:
            mine, theirs = socket.socketpair()
            try:
                worker = subprocess.Popen(
                    [sys.executable, "-m", "sdc_gym.envs.split_worker", str(theirs.fileno()),
                     str(os.getpid())], pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL,
                    env=environment)
            finally:
                theirs.close()
            connection = Connection(mine.detach())
            self._connections.append(connection)
            self._workers.append(worker)
            connection.send((entry_point, stop - start, kwargs))
        try:
            answers = self._gather()
        except BaseException:
            self.close()
            raise
        observation_space, action_space, metadata = answers[0]
        self.single_observation_space = observation_space
        self.single_action_space = action_space
        self.observation_space = batch_space(observation_space, num_envs)
        self.action_space = batch_space(action_space, num_envs)
        self.metadata = metadata
        self.autoreset_mode: AutoresetMode = metadata["autoreset_mode"]
        self.render_mode = None

    # ------------------------------------------------------------------ the pipes
    def _gather(self, name_block: bool = False) -> list[Any]:
        """Every worker's answer, in block order; the first error re-raised (after every
        answer is read, so the pipes stay in step), naming its block if ``name_block``
        (a step's: an env index in its message counts from the block's first env)."""
        answers, failure = [], None
        for connection, (start, stop) in zip(self._connections, self.bounds, strict=True):
            try:
                status, payload = connection.recv()
            except (EOFError, OSError) as error:
                status, payload = "error", WorkerError(
                    f"the worker of envs {start}..{stop - 1} ended unexpectedly ({error!r})")
            if status == "error" and failure is None:
                failure = (payload, start, stop)
            answers.append(payload)
        if failure is not None:
            error, start, stop = failure
            if name_block and error.args and isinstance(error.args[0], str):
                error.args = (f"{error.args[0]} (in the block of envs {start}..{stop - 1}: "
                              f"env k there is env {start} + k of the batch)",
                              *error.args[1:])
            raise error
        return answers

    def _ask(self, command: str, payloads: list[Any]) -> list[Any]:
        if self._closed:
            raise RuntimeError("the split env is closed")
        for connection, payload in zip(self._connections, payloads, strict=True):
            connection.send((command, payload))
        return self._gather(name_block=command == "step")

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        check_reset_options(options, type(self).__name__, (OPTION, RESET_MASK))
        mask = reset_mask(options, self.num_envs)
        if isinstance(seed, int | np.integer) and not isinstance(seed, bool | np.bool_):
            seeds: list[Any] = [int(seed) + start for start, _ in self.bounds]
        elif seed is None:
            seeds = [None] * self.processes
        else:
            if not isinstance(seed, list | tuple) or len(seed) != self.num_envs:
                raise ValueError(f"reset(seed=...) takes an int, None or {self.num_envs} "
                                 f"seeds, got {excerpt(seed)}")
            seeds = [list(seed[start:stop]) for start, stop in self.bounds]
        scenarios = batch_scenarios(options, self.num_envs)  # per env, checked here
        payloads = []
        for block, (start, stop) in enumerate(self.bounds):
            block_options = None if options is None else dict(options)
            if mask is not None:
                block_options[RESET_MASK] = mask[start:stop]  # type: ignore[index]
            if scenarios is not None:
                block_options[OPTION] = scenarios[start:stop]  # type: ignore[index]
            payloads.append({"seed": seeds[block], "options": block_options})
        answers = self._ask("reset", payloads)
        observations = _concatenate([obs for obs, _ in answers])
        return observations, merge_infos([info for _, info in answers], self.bounds,
                                         self.num_envs)

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray,
                                          dict[str, Any]]:
        if isinstance(actions, str | bytes) or not hasattr(actions, "__len__") or len(
                actions) != self.num_envs:
            raise ValueError(f"actions must hold one action per env (num_envs = "
                             f"{self.num_envs}), got {excerpt(actions)}")
        answers = self._ask("step", [actions[start:stop] for start, stop in self.bounds])
        observations = _concatenate([answer[0] for answer in answers])
        reward, terminated, truncated = (np.concatenate([answer[k] for answer in answers])
                                         for k in (1, 2, 3))
        infos = merge_infos([answer[4] for answer in answers], self.bounds, self.num_envs)
        return observations, reward, terminated, truncated, infos

    def close_extras(self, **kwargs: Any) -> None:
        if self._closed:
            return
        self._closed = True
        for connection in self._connections:
            try:
                connection.send(("close", None))
            except (BrokenPipeError, OSError):
                pass
        for worker in self._workers:
            try:
                worker.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                worker.kill()
                worker.wait()
        for connection in self._connections:
            connection.close()

    @property
    def worker_pids(self) -> list[int]:
        """The workers' process ids, block order."""
        return [worker.pid for worker in self._workers]

    def __del__(self) -> None:
        if not getattr(self, "_closed", True):
            self.close()


def split_or_batch(env_id: str, batch: type[VectorEnv], num_envs: int, processes: Any,
                   kwargs: dict[str, Any]) -> VectorEnv:
    """A vector entry point's body: ``batch(num_envs, **kwargs)`` in this process for
    ``processes=1``, else a :class:`SplitVectorEnv` of ``env_id``'s registered vector entry
    point (called in each worker with the default ``processes=1``)."""
    processes = check_processes(processes, check_env_count(num_envs))
    if processes == 1:
        return batch(num_envs, **kwargs)
    return SplitVectorEnv(env_id, registry[env_id].vector_entry_point, num_envs, processes,
                          **kwargs)


def vector_entry_point(env_id: str, batch: type[VectorEnv]) -> Callable[..., VectorEnv]:
    """The vector entry point of ``env_id`` (``gym.make_vec(env_id, num_envs=E,
    vectorization_mode="vector_entry_point", processes=P, **kwargs)``): ``batch`` in this
    process for ``processes=1`` (the default), else split over ``P`` worker processes."""
    def make(num_envs: int = 1, processes: int = 1, **kwargs: Any) -> VectorEnv:
        return split_or_batch(env_id, batch, num_envs, processes, kwargs)

    make.__doc__ = (f"Vector entry point of ``{env_id}``: one :class:`{batch.__name__}` in "
                    f"this process, or ``processes`` of them in worker processes "
                    f"(:mod:`sdc_gym.envs.split_vector`).")
    return make
