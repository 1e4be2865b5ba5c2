"""Python's ``math`` functions over arrays, value for value.

Several layers were defined (and their results recorded) on Python floats: the metrics'
``math.hypot`` (CPython's own correctly rounded algorithm, not the C library's), the motion
layer's ``math.atan2``, the braking curve's ``math.exp``, ``x ** 3`` (the C library's
``pow``). numpy's vectorized versions of these round differently in a few cases in a
thousand (its SIMD kernels, or libm's ``hypot``), and over an episode a last-bit
difference can change a decision. The batched layers therefore apply the very same Python
functions to every element (``map`` over ``tolist()``: about 50 ns a value); numpy's
``sin``, ``cos`` and ``sqrt`` do agree with ``math`` bit for bit (tested) and are used
directly.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def _binary(function: Callable[[float, float], float], a: ArrayLike, b: ArrayLike
            ) -> FloatArray:
    x, y = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if x.shape != y.shape:
        x, y = np.broadcast_arrays(x, y)
    flat = list(map(function, x.ravel().tolist(), y.ravel().tolist()))
    return np.array(flat, dtype=np.float64).reshape(x.shape)


def _unary(function: Callable[[float], float], a: ArrayLike) -> FloatArray:
    x = np.asarray(a, dtype=np.float64)
    return np.array(list(map(function, x.ravel().tolist())), dtype=np.float64).reshape(x.shape)


def hypot(x: ArrayLike, y: ArrayLike) -> FloatArray:
    """``math.hypot`` elementwise."""
    return _binary(math.hypot, x, y)


def atan2(y: ArrayLike, x: ArrayLike) -> FloatArray:
    """``math.atan2`` elementwise."""
    return _binary(math.atan2, y, x)


def exp(x: ArrayLike) -> FloatArray:
    """``math.exp`` elementwise."""
    return _unary(math.exp, x)


def power(x: ArrayLike, exponent: float) -> FloatArray:
    """Python's ``x ** exponent`` (the C library's ``pow``) elementwise."""
    return _binary(pow, x, exponent)
