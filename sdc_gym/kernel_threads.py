"""Batched kernels on more than one thread: the ``kernel_threads`` config setting.

A batched highway step spends ~83 % of its time in numba kernels whose outer loop runs
over the env axis, each env's row on its own cars (no sum or other reduction across
envs). Written with ``numba.prange`` instead of ``range``, such a loop is the same serial
loop when the function is compiled as usual (``parallel=False``: numba reads ``prange``
as ``range``) and a loop split over threads when it is compiled with ``parallel=True``.
Both variants run the same Python function, so there is one body per kernel:
:func:`parallel_twin` compiles the kernel's own code object a second time, under a name
of its own, with ``parallel=True``.

Bit for bit: numba's static schedule gives each thread a contiguous block of envs, and an
env's arithmetic is the same instructions whichever thread runs it (no reduction order
changes, no fast-math), so 1 and 2 threads give the same bits (``tests/test_kernel_
threads.py`` compares every observation, reward and info of batched episodes).

Cost: nothing unless a batch asks for more than one thread. The twins are compiled on the
first call of a batch with ``kernel_threads > 1`` (cached in ``__pycache__`` like every
kernel, as ``<name>__parallel``), so the default cold start and ``sdc_gym.precompile``
compile none of them; numba's threading layer is launched then too, not at import.

Threading layer: ``workqueue`` unless the user chose one (``NUMBA_THREADING_LAYER``) or
numba's threads already run. Measured on this project's shared 2-core machine
(docs/batched.md, "Two kernel threads"): omp's default spinning wait made a loaded
machine's calls up to 30x slower, omp with ``OMP_WAIT_POLICY=passive`` 0.8-0.9x,
workqueue broke even; workqueue needs no environment variable set before its library
loads. Its limit: workqueue must not run parallel kernels from two Python threads at once
(numba aborts); step two multi-threaded batches from one thread, or in processes.
"""

from __future__ import annotations

import functools
import os
import types
from collections.abc import Callable
from typing import Any

import numba
from numba.core.dispatcher import Dispatcher

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)
from sdc_gym.validation.rules import Number, check_value

PARALLEL_SUFFIX = "__parallel"
"""Appended to a kernel's qualified name for its parallel twin (its own cache files)."""

DEFAULT_LAYER = "workqueue"
"""The threading layer picked when the user chose none (see the module docstring)."""


def max_kernel_threads() -> int:
    """The most threads a kernel may use: numba's pool size, ``NUMBA_NUM_THREADS``
    (the CPU count unless set)."""
    return int(numba.config.NUMBA_NUM_THREADS)


def check_kernel_threads(value: Any, owner: str, key: str = "kernel_threads") -> int:
    """``value`` as a thread count, or a :class:`~sdc_gym.config.ConfigError` naming
    ``key``, the value and the valid choices (an int in 1..``NUMBA_NUM_THREADS``)."""
    top = max_kernel_threads()
    check_value(Number(1, top, integer=True, unit="threads",
                       why=f"1 runs the kernels serially; at most NUMBA_NUM_THREADS = {top}"),
                value, owner, key)
    return int(value)


@functools.cache
def parallel_twin(kernel: Dispatcher) -> Dispatcher:
    """``kernel``'s Python function compiled with its options plus ``parallel=True``:
    the same code object under the name ``<qualname>__parallel`` (numba's cache is
    keyed by the function's name and line, not its options, so the twin needs a name of
    its own to keep its machine code apart from the serial kernel's). Compiled lazily,
    at its first call."""
    source = kernel.py_func
    twin = types.FunctionType(source.__code__, source.__globals__, source.__name__,
                              source.__defaults__, source.__closure__)
    twin.__qualname__ = source.__qualname__ + PARALLEL_SUFFIX
    twin.__module__ = source.__module__
    twin.__doc__ = source.__doc__
    # (njit implies nopython and warns when it is passed again)
    options = {key: value for key, value in kernel.targetoptions.items() if key != "nopython"}
    options["parallel"] = True
    cached = kernel._cache.__class__.__name__ != "NullCache"
    return numba.njit(cache=cached, **options)(twin)


def _choose_layer() -> None:
    """Pick :data:`DEFAULT_LAYER` unless the user set a layer or numba's pool runs."""
    from numba.np.ufunc import parallel

    if "NUMBA_THREADING_LAYER" not in os.environ and not parallel._is_initialized:
        numba.config.THREADING_LAYER = DEFAULT_LAYER


class KernelThreads:
    """Which variant of a batched kernel to call: :meth:`pick` gives the kernel itself for
    one thread, else its :func:`parallel_twin` run on ``threads`` threads (numba's
    thread count set for the call and put back after it). One object is shared by the
    layers of a batch (traffic, motion), so :meth:`set` changes them all at once."""

    __slots__ = ("_picked", "threads")

    def __init__(self, threads: int = 1) -> None:
        self.threads = check_kernel_threads(threads, "KernelThreads", "threads")
        self._picked: dict[Dispatcher, Callable[..., Any]] = {}

    def set(self, threads: int) -> None:
        """Run the next calls on ``threads`` threads (the same bits on any number: e.g.
        a benchmark comparing thread counts on one batch)."""
        self.threads = check_kernel_threads(threads, "KernelThreads", "threads")

    def pick(self, kernel: Dispatcher) -> Callable[..., Any]:
        """``kernel`` or, with more than one thread, its parallel twin on them."""
        if self.threads == 1:
            return kernel
        call = self._picked.get(kernel)
        if call is None:
            call = self._picked[kernel] = self._threaded(parallel_twin(kernel))
        return call

    def _threaded(self, twin: Dispatcher) -> Callable[..., Any]:
        _choose_layer()

        def call(*args: Any) -> Any:
            previous = numba.get_num_threads()
            numba.set_num_threads(self.threads)
            try:
                return twin(*args)
            finally:
                numba.set_num_threads(previous)

        return call

    def __getstate__(self) -> int:
        return self.threads

    def __setstate__(self, threads: int) -> None:
        self.threads = threads
        self._picked = {}

    def __repr__(self) -> str:
        return f"KernelThreads({self.threads})"


SERIAL = KernelThreads(1)
"""The default: every kernel as compiled, on the calling thread."""

__all__ = ["DEFAULT_LAYER", "SERIAL", "KernelThreads", "check_kernel_threads",
           "max_kernel_threads", "parallel_twin"]
