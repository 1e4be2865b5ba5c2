"""How the track's numba kernels are compiled: :data:`kernel`, one decorator for all.

``@kernel`` is ``numba.njit(cache=True, _nrt=False)``:

* ``cache=True``: the machine code is written next to the module (``__pycache__``) and
  loaded by later processes, so only the first run after a change compiles (a fresh clone
  compiles every kernel once: ~45 s of the first track env on the loaded 2-core machine).
  numba checks only the file that defines a function, but a kernel here has the code of
  the kernels it calls from other modules compiled into it: a change to ``dbw_kernel.py``
  would leave the cached frame kernel of ``track_kernel.py`` stale. So for every numba
  function of this package the stamp that decides whether its cache is current is the
  hash of *all* the package's modules that use numba (:class:`PackageStampLocator`,
  installed when this module is imported, which every kernel module does first): any
  change to any kernel recompiles them all.
* ``_nrt=False``: no numba runtime (NRT) in the function. With the runtime every array a
  function receives, every array field of a NamedTuple argument and every view it takes
  is reference-counted with an atomic increment and decrement; a frame kernel that
  passes the world's state (a tuple of ~40 arrays) to its helpers paid ~0.8 us per call
  in those counts alone, about half of the track's frame time. The kernels only read and
  write arrays that Python owns (and keeps alive during the call), so they need no
  counting. The price: such a function cannot allocate (``np.empty``, ``.copy()``) or
  return a new array; numba refuses to compile one that tries, so a mistake is loud.

:func:`bind` is for a kernel that Python calls once per env step with the same arguments
(a world's state tuples): numba's dispatcher works out the types of its arguments at
every call to pick the machine code, and for a tuple of ~60 arrays that costs ~60 us, more
than the kernel's own work for one env; the bound function skips it.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from numba import njit, typeof
from numba.core import caching, config, event
from numba.core.dispatcher import Dispatcher

PACKAGE = Path(__file__).resolve().parent


@functools.lru_cache(maxsize=1)
def package_stamp() -> str:
    """The hash of every module of this package that uses numba (their bytes, by path)."""
    digest = hashlib.sha256()
    for path in sorted(PACKAGE.rglob("*.py")):
        source = path.read_bytes()
        if b"numba" in source or b"kernel_compiler" in source:
            digest.update(str(path.relative_to(PACKAGE)).encode() + b"\0" + source)
    return digest.hexdigest()


# Older numba releases name these _InTreeCacheLocator and _CacheImpl.
_IN_TREE = getattr(caching, "InTreeCacheLocator", None) or caching._InTreeCacheLocator
_CACHE_IMPL = getattr(caching, "CacheImpl", None) or caching._CacheImpl


class PackageStampLocator(_IN_TREE):  # type: ignore[misc, valid-type]
    """numba's in-tree cache (``__pycache__`` next to the module) for this package's
    functions, current only while no kernel module of the package changed (see the
    module docstring). Other packages' functions, and a ``NUMBA_CACHE_DIR`` set by the
    user, keep numba's own locators."""

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> PackageStampLocator | None:
        if config.CACHE_DIR or not Path(py_file).resolve().is_relative_to(PACKAGE):
            return None
        locator = super().from_function(py_func, py_file)
        if locator is not None:
            _prune_stale_files(locator.get_cache_path())
        return locator

    def get_source_stamp(self) -> str:
        return package_stamp()

    def get_disambiguator(self) -> str:
        # The stamp in the file names: numba unpickles an index's signatures before it
        # compares stamps, so an index written before a kernel's NamedTuple moved to
        # another module would fail to load (AttributeError) instead of going stale.
        return f"{super().get_disambiguator()}-{_short_stamp()}"


def _short_stamp() -> str:
    return package_stamp()[:_STAMP_CHARS]


_STAMP_CHARS = 12


@functools.cache
def _prune_stale_files(cache_path: str) -> None:
    """Delete the cache files in ``cache_path`` (a ``__pycache__`` of this package) that
    belong to another package stamp: they can never load again. Once per folder."""
    current = _short_stamp()
    for path in Path(cache_path).glob("*.nb[ic]"):
        stem = path.name.rsplit(".py", 1)[0]  # "module.qualname-lineno-stamp"
        if stem.rsplit("-", 1)[-1] != current:
            path.unlink(missing_ok=True)


if PackageStampLocator not in _CACHE_IMPL._locator_classes:
    _CACHE_IMPL._locator_classes.insert(0, PackageStampLocator)

kernel = njit(cache=True, _nrt=False)


def machine_code(function: Dispatcher, *args: Any) -> Callable[..., Any]:
    """``function``'s compiled entry point for the types of ``args`` (compiled or loaded
    from the cache now). It converts scalars as numba does but trusts arrays and tuples to
    have these types: call it only with arguments built the same way."""
    types = tuple(typeof(arg) for arg in args)
    function.compile(types)
    return function.overloads[types].entry_point


def bind(function: Dispatcher, *args: Any) -> Callable[[], Any]:
    """``function(*args)`` as a call without arguments: the machine code for the types of
    ``args`` is looked up once, here, and called on exactly these objects (arrays updated
    in place, never replaced) each time."""
    entry = machine_code(function, *args)

    def call() -> Any:
        return entry(*args)

    return call


class TypedCall:
    """``function`` for one owner that always passes arguments of the same types (its own
    state tuples, arrays it makes the same way, and ``float()``/``int()``/``bool()``
    scalars): the machine code is looked up at the first call (:func:`machine_code`) and
    later calls skip numba's dispatch (~5 us for a tuple of arrays, more than the work of
    a node of the drive-by-wire stack). Pickles as the function alone."""

    __slots__ = ("entry", "function")

    def __init__(self, function: Dispatcher) -> None:
        self.function = function
        self.entry: Callable[..., Any] | None = None

    def __call__(self, *args: Any) -> Any:
        if self.entry is None:
            self.entry = machine_code(self.function, *args)
        return self.entry(*args)

    def __getstate__(self) -> dict[str, Any]:
        return {"function": self.function}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.function = state["function"]
        self.entry = None


__all__ = ["PackageStampLocator", "TypedCall", "bind", "kernel", "machine_code", "package_stamp"]


class _CompileCounter(event.Listener):
    """Counts numba's compilations (cache misses only: a cache hit emits no event) of
    this package's functions and reports each to ``on_compile(name, count)``."""

    def __init__(self, on_compile: Callable[[str, int], None]) -> None:
        self.count = 0
        self._on_compile = on_compile

    def on_start(self, happening: Any) -> None:
        data = getattr(happening, "data", None)
        dispatcher = data.get("dispatcher") if isinstance(data, dict) else None
        function = getattr(dispatcher, "py_func", None)
        module = getattr(function, "__module__", "") or ""
        if module.startswith("sdc_gym"):
            self.count += 1
            self._on_compile(f"{module.rsplit('.', 1)[-1]}.{function.__name__}", self.count)

    def on_end(self, happening: Any) -> None:
        pass


class _FirstUseNotice(event.Listener):
    """Says on stderr that this package's kernels are compiling, wherever that happens
    (a user's own script, a test, a notebook) and not only under :func:`compile_progress`:
    a line at the first compilation of a process, then one every :data:`NOTICE_EVERY`
    seconds while compilations go on, so that a fresh clone's first step is not a silent
    wait. Quiet inside :func:`compile_progress` (it shows its own status) and with
    ``SDC_GYM_COMPILE_NOTICE=0``."""

    def __init__(self) -> None:
        self.count = 0
        self.started = 0.0
        self.reported = 0.0
        self.quiet_depth = 0

    def on_start(self, happening: Any) -> None:
        data = getattr(happening, "data", None)
        dispatcher = data.get("dispatcher") if isinstance(data, dict) else None
        function = getattr(dispatcher, "py_func", None)
        module = getattr(function, "__module__", "") or ""
        if self.quiet_depth or not module.startswith("sdc_gym"):
            return
        now = time.perf_counter()
        self.count += 1
        if self.count == 1:
            self.started = self.reported = now
            print("sdc-gym: compiling the kernels on first use (once per clone or install, "
                  "then loaded from __pycache__; about 20-40 s of CPU per env) ...",
                  file=sys.stderr, flush=True)
        elif now - self.reported >= NOTICE_EVERY:
            self.reported = now
            print(f"sdc-gym: ... {self.count} kernels compiled, {now - self.started:.0f} s, "
                  f"now {module.rsplit('.', 1)[-1]}.{function.__name__}",
                  file=sys.stderr, flush=True)

    def on_end(self, happening: Any) -> None:
        pass


NOTICE_EVERY = 10.0
"""Seconds between two progress lines of the first-use notice."""

_NOTICE = _FirstUseNotice()
if os.environ.get("SDC_GYM_COMPILE_NOTICE", "1") != "0":
    event.register("numba:compile", _NOTICE)


@contextlib.contextmanager
def compile_progress(console: Any = None) -> Iterator[_CompileCounter]:
    """Show numba compiling this package's kernels while the block runs.

    The first run on a fresh checkout (or after a change to any kernel module) compiles
    every kernel it uses, about a minute or two of CPU in all, and caches the machine code
    in ``__pycache__``; later runs load it in a second or two and show nothing. On a
    terminal a status line counts the kernels; elsewhere (logs, CI) one line says that
    compiling has begun and one how long it took.
    """
    from rich.console import Console

    console = console if console is not None else Console(stderr=True)
    started = time.perf_counter()
    status: Any = None

    def on_compile(name: str, count: int) -> None:
        nonlocal status
        text = (f"compiling sdc-gym's kernels on first use (cached for later runs): "
                f"{count} compiled, {time.perf_counter() - started:.0f} s, now {name}")
        if console.is_terminal:
            if status is None:
                status = console.status(text)
                status.start()
            else:
                status.update(text)
        elif count == 1:
            console.print("compiling sdc-gym's kernels on first use (a minute or two of "
                          "CPU; cached for later runs) ...", highlight=False)

    counter = _CompileCounter(on_compile)
    event.register("numba:compile", counter)
    _NOTICE.quiet_depth += 1
    try:
        yield counter
    finally:
        _NOTICE.quiet_depth -= 1
        event.unregister("numba:compile", counter)
        if status is not None:
            status.stop()
        if counter.count:
            console.print(f"compiled {counter.count} sdc-gym kernels in "
                          f"{time.perf_counter() - started:.0f} s (cached for later runs)",
                          highlight=False)
