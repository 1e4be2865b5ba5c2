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
"""

from __future__ import annotations

from numba import njit

kernel = njit(cache=True, _nrt=False)

__all__ = ["kernel"]
