"""Linear algebra in one fixed order of operations, without BLAS or LAPACK.

numpy hands ``a @ b``, ``np.dot`` and ``np.linalg`` to OpenBLAS, which picks its kernels
by processor at run time (``OPENBLAS_CORETYPE``): a Haswell, a SkylakeX and a Sandybridge
kernel sum the same products in different orders, with or without fused multiply-adds,
so the last bit of a result depends on the machine. On the simulation's path a last-bit
difference in a road's arc length or a Kalman gain is enough to change a decision some
minutes later, so the few products the simulation needs are computed here instead, in
one order on every machine:

* :func:`dot_rows` (``rows @ weights``) and :func:`matmul` sum their products the way
  OpenBLAS's Haswell ``dgemv`` kernel does (four lanes of fused multiply-adds over the
  terms in order, then the lanes added pairwise, ``(l0 + l2) + (l1 + l3)``): any fixed
  order would do, this one keeps every episode recorded before the change (on Haswell
  and SkylakeX machines) valid;
* :func:`solve_2x2` is Gaussian elimination with partial pivoting in the operations
  LAPACK's ``dgesv`` makes with OpenBLAS's kernels (the multiplier by the pivot's
  reciprocal, the forward substitution unfused, the back substitution fused: the
  SkylakeX kernels' results for the built-in highway, Haswell's and SkylakeX's for the
  built-in track, so their recorded episodes stay valid);
* :func:`inverse` is Gauss-Jordan elimination with partial pivoting.

A fused multiply-add (:func:`fma`, one rounding of ``a * b + c``) is an IEEE 754
operation with one correct result: LLVM emits the processor's instruction where it has
one and the C library's exact ``fma`` elsewhere, so the bits do not depend on which.
"""

from __future__ import annotations

import numpy as np
from numba import njit, types
from numba.extending import intrinsic
from numpy.typing import ArrayLike, NDArray

import sdc_gym.kernel_compiler  # noqa: F401  (the package's cache locator, before any njit)

FloatArray = NDArray[np.float64]

_LANES = 4  # the Haswell kernel's vector width in doubles


@intrinsic
def _fma_intrinsic(typingctx, a, b, c):
    """``llvm.fma.f64``: a * b + c rounded once."""
    signature = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, sig, args):
        return builder.fma(*args)

    return signature, codegen


@njit(cache=True, inline="always")
def fma(a: float, b: float, c: float) -> float:
    """``a * b + c`` with a single rounding (IEEE 754 fusedMultiplyAdd)."""
    return _fma_intrinsic(a, b, c)


@njit(cache=True, inline="always")
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """``sum(a[k] * b[k])`` in the fixed order (see the module docstring); a tail of
    fewer than four terms is added one fused multiply-add at a time after the lanes."""
    n = a.shape[0]
    l0 = 0.0
    l1 = 0.0
    l2 = 0.0
    l3 = 0.0
    k = 0
    while k + _LANES <= n:
        l0 = fma(a[k], b[k], l0)
        l1 = fma(a[k + 1], b[k + 1], l1)
        l2 = fma(a[k + 2], b[k + 2], l2)
        l3 = fma(a[k + 3], b[k + 3], l3)
        k += _LANES
    total = (l0 + l2) + (l1 + l3)
    while k < n:
        total = fma(a[k], b[k], total)
        k += 1
    return total


@njit(cache=True)
def _dot_rows(rows: np.ndarray, weights: np.ndarray, out: np.ndarray) -> None:
    for i in range(rows.shape[0]):
        out[i] = _dot(rows[i], weights)


@njit(cache=True)
def _matmul(a: np.ndarray, b_columns: np.ndarray, out: np.ndarray) -> None:
    for i in range(a.shape[0]):
        for j in range(b_columns.shape[0]):
            out[i, j] = _dot(a[i], b_columns[j])


def dot_rows(rows: ArrayLike, weights: ArrayLike) -> FloatArray:
    """``rows @ weights`` for rows ``(..., m)`` and weights ``(m,)``: shape ``(...)``."""
    table = np.ascontiguousarray(rows, dtype=np.float64)
    vector = np.ascontiguousarray(weights, dtype=np.float64)
    if vector.ndim != 1 or table.shape[-1:] != vector.shape:
        raise ValueError(f"dot_rows: shapes {table.shape} and {vector.shape} do not match")
    flat = table.reshape(-1, vector.shape[0])
    out = np.empty(flat.shape[0])
    _dot_rows(flat, vector, out)
    return out.reshape(table.shape[:-1])


def matmul(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """``a @ b`` for 2-D ``a`` and ``b`` (a 1-D ``b`` is a column: the result is 1-D)."""
    left = np.ascontiguousarray(a, dtype=np.float64)
    right = np.asarray(b, dtype=np.float64)
    vector = right.ndim == 1
    columns = np.ascontiguousarray((right[:, None] if vector else right).T)
    if left.ndim != 2 or columns.ndim != 2 or left.shape[1] != columns.shape[1]:
        raise ValueError(f"matmul: shapes {left.shape} and {right.shape} do not match")
    out = np.empty((left.shape[0], columns.shape[0]))
    _matmul(left, columns, out)
    return out[:, 0] if vector else out


def solve_2x2(matrix: ArrayLike, rhs: ArrayLike) -> tuple[float, float]:
    """The solution ``x`` of ``matrix @ x = rhs`` for a non-singular 2 x 2 ``matrix``."""
    (a00, a01), (a10, a11) = np.asarray(matrix, dtype=np.float64).tolist()
    b0, b1 = np.asarray(rhs, dtype=np.float64).tolist()
    if abs(a10) > abs(a00):  # partial pivoting
        a00, a01, a10, a11, b0, b1 = a10, a11, a00, a01, b1, b0
    if a00 == 0.0:
        raise ValueError("solve_2x2: the matrix is singular")
    factor = a10 * (1.0 / a00)  # dgetf2 scales the column by the pivot's reciprocal
    u11 = fma(-factor, a01, a11)
    if u11 == 0.0:
        raise ValueError("solve_2x2: the matrix is singular")
    y1 = b1 - factor * b0  # forward substitution unfused, back substitution fused
    x1 = y1 / u11
    return fma(-a01, x1, b0) / a00, x1


@njit(cache=True)
def _inverse(a: np.ndarray, out: np.ndarray) -> bool:
    n = a.shape[0]
    work = a.copy()
    for i in range(n):
        for j in range(n):
            out[i, j] = 1.0 if i == j else 0.0
    for col in range(n):
        pivot = col
        for row in range(col + 1, n):
            if abs(work[row, col]) > abs(work[pivot, col]):
                pivot = row
        if work[pivot, col] == 0.0:
            return False
        if pivot != col:
            for j in range(n):
                work[col, j], work[pivot, j] = work[pivot, j], work[col, j]
                out[col, j], out[pivot, j] = out[pivot, j], out[col, j]
        scale = 1.0 / work[col, col]
        for j in range(n):
            work[col, j] *= scale
            out[col, j] *= scale
        for row in range(n):
            if row != col:
                factor = work[row, col]
                if factor != 0.0:
                    for j in range(n):
                        work[row, j] = fma(-factor, work[col, j], work[row, j])
                        out[row, j] = fma(-factor, out[col, j], out[row, j])
    return True


def inverse(matrix: ArrayLike) -> FloatArray:
    """The inverse of a square non-singular ``matrix`` (``np.linalg.inv`` without LAPACK).

    Raises ``np.linalg.LinAlgError`` for a singular matrix, as ``np.linalg.inv`` does.
    """
    a = np.ascontiguousarray(matrix, dtype=np.float64)
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ValueError(f"inverse: a square matrix is needed, got shape {a.shape}")
    out = np.empty_like(a)
    if not _inverse(a, out):
        raise np.linalg.LinAlgError("Singular matrix")
    return out
