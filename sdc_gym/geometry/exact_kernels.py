"""CPython's ``math.hypot`` and ``math.remainder`` for numba kernels, value for value.

The track's layers were defined on Python floats, and numba calls the C library where
CPython has its own algorithms: ``math.hypot`` (CPython's ``vector_norm``: lossless
scaling and squaring, a differential correction; the C library's ``hypot`` differs in
the last bit for ~0.2 % of inputs) and ``math.remainder`` (which numba lacks). These are
ports of CPython's code (``Modules/mathmodule.c``); the tests compare them with ``math``
on random inputs. Every other function the kernels use (``sqrt``, ``sin``, ``cos``,
``tan``, ``atan``, ``exp``, ``expm1``, ``floor``, float ``%``) is the C library's in
both, and numba neither reorders nor fuses float arithmetic without ``fastmath``.
"""

from __future__ import annotations

import math

from sdc_gym.kernel_compiler import kernel

_SPLIT = 134217729.0  # 2**27 + 1: Dekker's splitting constant
_DBL_MIN = 2.2250738585072014e-308


@kernel
def _dl_mul(x: float, y: float) -> tuple[float, float]:
    """x * y as an unevaluated sum hi + lo, exactly (Dekker's mul12)."""
    xx = x * _SPLIT
    yy = y * _SPLIT
    hx = xx - (xx - x)
    hy = yy - (yy - y)
    tx = x - hx
    ty = y - hy
    z = x * y
    zz = ((hx * hy - z) + hx * ty + tx * hy) + tx * ty
    return z, zz


@kernel
def _norm2(x0: float, x1: float, largest: float) -> float:
    """CPython's ``vector_norm`` for two finite non-negative coordinates, max > 0."""
    _, max_e = math.frexp(largest)
    if max_e < -1023:  # subnormals: ldexp(1, -max_e) would overflow
        return _DBL_MIN * _norm2(x0 / _DBL_MIN, x1 / _DBL_MIN, largest / _DBL_MIN)
    scale = math.ldexp(1.0, -max_e)
    csum = 1.0
    frac1 = 0.0
    frac2 = 0.0
    for value in (x0, x1):
        x = value * scale
        hi, lo = _dl_mul(x, x)
        total = csum + hi  # dl_fast_sum(csum, hi)
        frac2 += hi - (total - csum)
        csum = total
        frac1 += lo
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    hi, lo = _dl_mul(-h, h)
    total = csum + hi
    frac2 += hi - (total - csum)
    csum = total
    frac1 += lo
    x = csum - 1.0 + (frac1 + frac2)
    h += x / (2.0 * h)
    return h / scale


@kernel
def py_hypot(x: float, y: float) -> float:
    """``math.hypot(x, y)`` exactly as CPython computes it."""
    ax = abs(x)
    ay = abs(y)
    if math.isinf(ax) or math.isinf(ay):
        return math.inf
    if math.isnan(ax) or math.isnan(ay):
        return math.nan
    largest = ax if ax > ay else ay
    if largest == 0.0:
        return largest
    return _norm2(ax, ay, largest)


@kernel
def py_remainder(x: float, y: float) -> float:
    """``math.remainder(x, y)`` (IEEE 754 remainder, exact) for finite x and y != 0."""
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
    else:  # half way: the even multiple (see CPython's m_remainder)
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
