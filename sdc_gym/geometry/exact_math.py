"""Python's ``math`` functions for compiled kernels and over arrays, value for value.

Several layers were defined (and their results recorded) on Python floats: the metrics'
``math.hypot``, the motion layer's ``math.atan2``, the braking curve's ``math.exp``,
``x ** 3`` (the C library's ``pow``). numpy's vectorized versions of these round
differently in a few cases in a thousand (its SIMD kernels), and over an episode a
last-bit difference can change a decision. numba compiles ``math.atan2``, ``math.exp``,
``math.sin``, ``math.cos`` and ``x ** y`` to the very C library calls CPython makes, so a
compiled kernel keeps Python's numbers; ``math.hypot`` is the exception: CPython computes
it with its own correctly rounded algorithm (``vector_norm`` in ``mathmodule.c``: lossless
scaling by a power of two, lossless squaring, a differential correction), while numba
(like numpy) calls the C library's ``hypot``, which differs in about 0.5 % of random
inputs. :func:`py_hypot` is CPython's algorithm, compiled: equal to ``math.hypot`` for
every finite input of normal magnitude and for zeros, infinities and NaNs (tested on
millions of random pairs); for subnormal inputs (below 2.2e-308, never a distance here) it
may differ in the last bit.

The array functions (:func:`hypot`, :func:`atan2`, :func:`exp`, :func:`power`) apply them
elementwise in one compiled loop. :func:`py_mod` is Python's float ``%`` with a shortcut
for the usual case of a value already in range. The track's layers add the rest of what
Python computes differently from a compiled default: :func:`py_remainder`
(``math.remainder``, which numba lacks), :func:`py_min` / :func:`py_max` (Python's
``min`` / ``max`` of two floats: the first argument on ties, so ``max(-0.0, 0.0)`` is
-0.0) and :func:`np_minimum` / :func:`np_maximum` (numpy's, NaN propagating). numba
neither reorders nor fuses float arithmetic without ``fastmath``, so everything else a
kernel computes is what Python computes.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray

from sdc_gym.geometry.fixed_order import fma
from sdc_gym.kernel_compiler import kernel
from sdc_gym.kernel_threads import SERIAL, KernelThreads

FloatArray = NDArray[np.float64]

_VELTKAMP = 134217729.0  # 2**27 + 1: splits a double into two 26-bit halves
_DBL_MIN = 2.2250738585072014e-308  # smallest normal double


@njit(cache=True, inline="always")
def _square_parts(x: float) -> tuple[float, float]:
    """``x * x`` as hi + lo exactly (Dekker's product of the Veltkamp halves: the same
    operations as CPython's square step)."""
    return _product_parts(x, x)


@njit(cache=True, inline="always")
def _product_parts(x: float, y: float) -> tuple[float, float]:
    """``x * y`` as hi + lo exactly (Dekker)."""
    t = x * _VELTKAMP
    xh = t - (t - x)
    xl = x - xh
    t = y * _VELTKAMP
    yh = t - (t - y)
    yl = y - yh
    p = xh * yh
    q = xh * yl + xl * yh
    z = p + q
    return z, p - z + q + xl * yl


@njit(cache=True)
def py_hypot(a: float, b: float) -> float:
    """``math.hypot(a, b)``: CPython's algorithm (see the module docstring)."""
    x0 = abs(a)
    x1 = abs(b)
    if math.isinf(x0) or math.isinf(x1):
        return math.inf
    if math.isnan(x0) or math.isnan(x1):
        return math.nan
    largest = x0 if x0 > x1 else x1
    if largest == 0.0:
        return 0.0
    if largest < _DBL_MIN:  # subnormal: scaled up to normal first
        return _DBL_MIN * py_hypot(x0 / _DBL_MIN, x1 / _DBL_MIN)
    exponent = math.frexp(largest)[1]
    scale = math.ldexp(1.0, -exponent)
    csum = 1.0
    frac1 = 0.0
    frac2 = 0.0
    x = x0 * scale  # lossless scaling
    hi, lo = _square_parts(x)  # lossless squaring
    total = csum + hi  # lossless addition
    frac2 += (csum - total) + hi
    csum = total
    frac1 += lo
    x = x1 * scale
    hi, lo = _square_parts(x)
    total = csum + hi
    frac2 += (csum - total) + hi
    csum = total
    frac1 += lo
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    hi, lo = _product_parts(-h, h)
    total = csum + hi
    frac2 += (csum - total) + hi
    csum = total
    frac1 += lo
    x = csum - 1.0 + (frac1 + frac2)
    h += x / (2.0 * h)  # differential correction
    return h / scale


@njit(cache=True)
def _hypot_loop(x: np.ndarray, y: np.ndarray, out: np.ndarray) -> None:
    for i in range(x.size):
        out[i] = py_hypot(x[i], y[i])


@njit(cache=True)
def _atan2_loop(y: np.ndarray, x: np.ndarray, out: np.ndarray) -> None:
    for i in prange(x.size):  # elements apart: a thread each in the parallel twin
        out[i] = math.atan2(y[i], x[i])


@njit(cache=True)
def _exp_loop(x: np.ndarray, out: np.ndarray) -> None:
    for i in range(x.size):
        out[i] = math.exp(x[i])


@njit(cache=True)
def _sin_loop(x: np.ndarray, out: np.ndarray) -> None:
    for i in range(x.size):
        out[i] = math.sin(x[i])


@njit(cache=True)
def _cos_loop(x: np.ndarray, out: np.ndarray) -> None:
    for i in range(x.size):
        out[i] = math.cos(x[i])


@njit(cache=True)
def _log10_loop(x: np.ndarray, out: np.ndarray) -> None:
    for i in range(x.size):
        out[i] = math.log10(x[i])


@njit(cache=True)
def _complex_abs_loop(re: np.ndarray, im: np.ndarray, out: np.ndarray) -> None:
    for i in range(re.size):
        out[i] = numpy_complex_abs(re[i], im[i])


@njit(cache=True, inline="always")
def numpy_complex_abs(re: float, im: float) -> float:
    """``np.abs(re + 1j * im)`` as numpy's SIMD kernel computes it on x86-64-v3 and v4
    processors: ``larger * sqrt(fma(ratio, ratio, 1))`` with ``ratio = smaller / larger``
    (``loops_unary_complex``; its baseline kernel, without the fused multiply-add, rounds
    differently in about half of all cases). Finite inputs only: the simulation's."""
    a = abs(re)
    b = abs(im)
    larger = a if a > b else b
    smaller = b if a > b else a
    if larger == 0.0:
        return 0.0
    ratio = smaller / larger
    return math.sqrt(fma(ratio, ratio, 1.0)) * larger


@njit(cache=True)
def _fused_loop(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray,
                out: np.ndarray) -> None:
    for i in range(a.size):
        out[i] = fma(a[i], b[i], c[i] * d[i])


@njit(cache=True)
def _power_loop(x: np.ndarray, exponent: np.ndarray, out: np.ndarray) -> None:
    for i in range(x.size):
        out[i] = x[i] ** exponent[i]


def _flat_pair(a: ArrayLike, b: ArrayLike) -> tuple[FloatArray, FloatArray, tuple[int, ...]]:
    x, y = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if x.shape != y.shape:
        x, y = np.broadcast_arrays(x, y)
    return np.ascontiguousarray(x).ravel(), np.ascontiguousarray(y).ravel(), x.shape


def hypot(x: ArrayLike, y: ArrayLike) -> FloatArray:
    """``math.hypot`` elementwise."""
    a, b, shape = _flat_pair(x, y)
    out = np.empty(a.size)
    _hypot_loop(a, b, out)
    return out.reshape(shape)


def atan2(y: ArrayLike, x: ArrayLike, threads: KernelThreads = SERIAL) -> FloatArray:
    """``math.atan2`` elementwise (on ``threads``' threads: the same values)."""
    a, b, shape = _flat_pair(y, x)
    out = np.empty(a.size)
    threads.pick(_atan2_loop)(a, b, out)
    return out.reshape(shape)


def exp(x: ArrayLike) -> FloatArray:
    """``math.exp`` elementwise."""
    return _unary(_exp_loop, x)


def _unary(loop: Any, x: ArrayLike) -> FloatArray:
    a = np.asarray(x, dtype=np.float64)  # (not ascontiguousarray: it makes 0-d arrays 1-d)
    out = np.empty(a.size)
    loop(np.ascontiguousarray(a.ravel()), out)
    return out.reshape(a.shape)


def sin(x: ArrayLike) -> FloatArray:
    """``math.sin`` elementwise (numpy's ``sin`` has SIMD kernels chosen per processor)."""
    return _unary(_sin_loop, x)


def cos(x: ArrayLike) -> FloatArray:
    """``math.cos`` elementwise."""
    return _unary(_cos_loop, x)


def log10(x: ArrayLike) -> FloatArray:
    """``math.log10`` elementwise (for positive finite values)."""
    return _unary(_log10_loop, x)


def complex_abs(z: ArrayLike) -> FloatArray:
    """``np.abs`` of a complex array, computed the same way on every processor (see
    :func:`numpy_complex_abs`)."""
    values = np.asarray(z, dtype=np.complex128)
    re = np.ascontiguousarray(values.real).ravel()
    im = np.ascontiguousarray(values.imag).ravel()
    out = np.empty(re.size)
    _complex_abs_loop(re, im, out)
    return out.reshape(values.shape)


def fused_product_sum(a: ArrayLike, b: ArrayLike, c: ArrayLike, d: ArrayLike) -> FloatArray:
    """``a * b + c * d`` rounded as numpy's complex multiplication rounds each part on
    x86-64-v3 and v4 processors: ``fma(a, b, c * d)`` (``(p + iq)(r + is)`` has real part
    ``fma(p, r, -(q s))`` and imaginary part ``fma(p, s, q r)``; numpy's baseline kernel,
    without the fused multiply-add, rounds differently in a third of all cases)."""
    arrays = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64) for v in (a, b, c, d)))
    flat = [np.ascontiguousarray(v).ravel() for v in arrays]
    out = np.empty(flat[0].size)
    _fused_loop(*flat, out)
    return out.reshape(arrays[0].shape)


def power(x: ArrayLike, exponent: ArrayLike) -> FloatArray:
    """Python's ``x ** exponent`` (the C library's ``pow``) elementwise."""
    a, b, shape = _flat_pair(x, exponent)
    out = np.empty(a.size)
    _power_loop(a, b, out)
    return out.reshape(shape)


@njit(cache=True, inline="always")
def py_mod(x: float, m: float) -> float:
    """Python's ``x % m`` for ``m > 0`` (numpy's ``remainder``): ``x`` itself when it
    already lies in ``(0, m)``, which is what the C library's ``fmod`` returns there,
    without its cost; otherwise the full rule (``fmod``, then the divisor's sign)."""
    if 0.0 < x < m:
        return x
    return x % m


@kernel
def py_remainder(x: float, y: float) -> float:
    """``math.remainder(x, y)``: the IEEE 754 remainder, exact (CPython's ``m_remainder``:
    ``x - n y`` with ``n`` the integer nearest ``x / y``, ties to even)."""
    if math.isnan(x) or math.isnan(y):
        return math.nan
    if math.isinf(x) or y == 0.0:
        return math.nan
    if math.isinf(y):
        return x
    absx = abs(x)
    absy = abs(y)
    m = absx % absy  # fmod: both are positive
    c = absy - m
    if m < c:
        r = m
    elif m > c:
        r = -c
    else:  # half way: the even multiple
        r = m - 2.0 * ((0.5 * (absx - m)) % absy)
    return math.copysign(1.0, x) * r


@kernel
def py_max(a: float, b: float) -> float:
    """Python's ``max(a, b)``: ``a`` unless ``b > a`` (so ``max(-0.0, 0.0)`` is -0.0)."""
    return b if b > a else a


@kernel
def py_min(a: float, b: float) -> float:
    """Python's ``min(a, b)``: ``a`` unless ``b < a``."""
    return b if b < a else a


@kernel
def np_maximum(a: float, b: float) -> float:
    """``np.maximum(a, b)`` for two floats (NaN propagates; ``a`` on ties)."""
    return a if (a >= b or a != a) else b


@kernel
def np_minimum(a: float, b: float) -> float:
    """``np.minimum(a, b)`` for two floats (NaN propagates; ``a`` on ties)."""
    return a if (a <= b or a != a) else b
