"""numpy ``Generator`` draws inside compiled kernels, from the generator's own state.

A kernel that takes a ``numpy.random.Generator`` argument pays numba's unboxing of it on
every call (a handful of ctypes look-ups, about 8 us: more than the rest of a respawn).
Here an env's generator is reached through the addresses of its bit generator's state
and ``next_*`` functions (:func:`generator_pointers`, taken once per generator), and the
draws are numpy's own algorithms on top of them: :func:`random` is ``Generator.random``
(the bit generator's ``next_double``), :func:`uniform` ``Generator.uniform`` (``low +
(high - low) * next_double``), :func:`integers` ``Generator.integers`` for a range that
fits 32 bits (Lemire's bounded draw on ``next_uint32``, as numpy's
``random_bounded_uint64_fill`` does). They advance the very same state, so a kernel's
draws interleave with Python's calls on the generator exactly as if Python had made
them (tested against numpy, draw for draw).
"""

from __future__ import annotations

import ctypes

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic
from numpy.typing import NDArray

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)

STATE, NEXT_UINT64, NEXT_UINT32, NEXT_DOUBLE = range(4)


def generator_pointers(rng: np.random.Generator) -> NDArray[np.uint64]:
    """The state and ``next_uint64``, ``next_uint32``, ``next_double`` addresses of
    ``rng``'s bit generator (valid while ``rng`` lives; its state changes in place)."""
    interface = rng.bit_generator.ctypes
    pointers = [interface.state_address]
    for name in ("next_uint64", "next_uint32", "next_double"):
        pointers.append(ctypes.cast(getattr(interface, name), ctypes.c_void_p).value)
    return np.array(pointers, dtype=np.uint64)


def _call(return_type: types.Type, name: str):
    @intrinsic
    def call(typingctx, function, state):
        sig = return_type(types.uint64, types.uint64)

        def codegen(context, builder, signature, args):
            address, state_address = args
            value_type = context.get_value_type(return_type)
            pointer_type = ir.IntType(8).as_pointer()
            function_type = ir.FunctionType(value_type, (pointer_type,))
            target = builder.inttoptr(address, function_type.as_pointer())
            return builder.call(target, (builder.inttoptr(state_address, pointer_type),))

        return sig, codegen

    call.__name__ = name
    return call


_next_double = _call(types.float64, "next_double")
_next_uint32 = _call(types.uint32, "next_uint32")


@njit(cache=True, inline="always")
def random(pointers: np.ndarray) -> float:
    """``Generator.random()``."""
    return _next_double(pointers[NEXT_DOUBLE], pointers[STATE])


@njit(cache=True, inline="always")
def uniform(pointers: np.ndarray, low: float, high: float) -> float:
    """``Generator.uniform(low, high)``."""
    span = high - low
    return low + span * _next_double(pointers[NEXT_DOUBLE], pointers[STATE])


@njit(cache=True, inline="always")
def integers(pointers: np.ndarray, high: int) -> int:
    """``Generator.integers(0, high)`` for ``2 <= high <= 2**32`` (Lemire's method on
    32-bit draws, rejecting the biased ones, as numpy)."""
    bound = np.uint64(high)  # the range's size: numpy's rng + 1
    m = np.uint64(_next_uint32(pointers[NEXT_UINT32], pointers[STATE])) * bound
    leftover = m & np.uint64(0xFFFFFFFF)
    if leftover < bound:
        threshold = (np.uint64(0xFFFFFFFF) - (bound - np.uint64(1))) % bound
        while leftover < threshold:
            m = np.uint64(_next_uint32(pointers[NEXT_UINT32], pointers[STATE])) * bound
            leftover = m & np.uint64(0xFFFFFFFF)
    return int(m >> np.uint64(32))
