"""How the track's numba kernels are compiled: :data:`kernel`, one decorator for all.

``@kernel`` is ``numba.njit(cache=True, _nrt=False)``:

* ``cache=True``: the machine code is written next to the module (``__pycache__``) and
  loaded by later processes, so only the first import after a change compiles.
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

from collections.abc import Callable
from typing import Any

from numba import njit, typeof
from numba.core.dispatcher import Dispatcher

kernel = njit(cache=True, _nrt=False)


def bind(function: Dispatcher, *args: Any) -> Callable[[], Any]:
    """``function(*args)`` as a call without arguments: the machine code for the types of
    ``args`` is looked up (compiled or loaded from the cache) once, here, and called on
    exactly these objects (arrays updated in place, never replaced) each time."""
    types = tuple(typeof(arg) for arg in args)
    function.compile(types)
    entry = function.overloads[types].entry_point

    def call() -> Any:
        return entry(*args)

    return call


__all__ = ["bind", "kernel"]
