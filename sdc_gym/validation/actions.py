"""One check of an action's type, dtype and shape, shared by every env's ``step``.

An action is accepted only as real numbers: a NumPy array of an int or float dtype, a
Python number, or a (nested) list or tuple of numbers. Refused, with a ``ValueError``
that names the expected shape and dtype: bool arrays (``True`` is not full throttle),
complex arrays (NumPy would drop the imaginary part with only a warning), strings and
numeric strings, object arrays, ragged lists, and any other shape (no silent reshape of
``(1, 2)`` into ``(2,)``). The envs call these before any state changes, so a rejected
action leaves the env exactly as it was.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.config import excerpt

REAL_KINDS = "iuf"  # NumPy dtype kinds of real numbers: signed, unsigned, float
DTYPE_TEXT = "a real dtype (int or float; not bool, complex, str or object)"


def _shape_text(shape: tuple[int | None, ...]) -> str:
    return "(" + ", ".join("m" if size is None else str(size) for size in shape) + (
        ",)" if len(shape) == 1 else ")")


def real_array(action: Any, shape: tuple[int | None, ...] | None, what: str = "action",
               meaning: str = "") -> NDArray[np.float64]:
    """``action`` as a float64 array, or a ``ValueError`` naming the expected ``shape``
    (``None`` in it: any size; ``shape=None``: any shape, checked by the caller) and dtype.
    ``meaning`` (e.g. ``"[throttle, brake_torque, steering_wheel_angle]"``) goes in the
    message."""
    expected = (f"{what} must be an array" + ("" if shape is None else
                                              f" of shape {_shape_text(shape)}")
                + f" with {DTYPE_TEXT}" + (f": {meaning}" if meaning else ""))
    if isinstance(action, np.ndarray):
        array = action
    elif isinstance(action, str | bytes):
        raise ValueError(f"{expected}; got the string {excerpt(action)}")
    else:
        try:
            array = np.asarray(action)
        except (ValueError, TypeError) as error:  # ragged lists and other non-arrays
            raise ValueError(f"{expected}; got {excerpt(action)} ({error})") from None
    if array.dtype.kind not in REAL_KINDS:
        raise ValueError(f"{expected}; got dtype {array.dtype} with shape {array.shape}")
    if shape is not None and (len(array.shape) != len(shape) or any(
            size is not None and size != actual for size, actual in zip(shape, array.shape,
                                                                         strict=True))):
        raise ValueError(f"{expected}; got shape {array.shape}")
    return array.astype(np.float64, copy=False)


def discrete_index(action: Any, count: int, names: tuple[str, ...] | list[str] = ()) -> int:
    """A ``Discrete(count)`` action as an int: a Python or NumPy int, or an int array of
    shape ``()`` or ``(1,)`` (what vector envs hand out); bools and floats are refused."""
    value = action
    if isinstance(value, np.ndarray) and value.shape in ((), (1,)) \
            and value.dtype.kind in "iu":
        value = value.reshape(()).item()
    valid = f"0..{count - 1}" + (f" = {list(names)}" if names else "")
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise ValueError(f"a Discrete({count}) action is an int in {valid} (a Python or "
                         "NumPy int, or an int array of shape () or (1,)); got "
                         f"{excerpt(action)}")
    if not 0 <= value < count:
        raise ValueError(f"action {value} out of range; valid: {valid}")
    return int(value)


def discrete_indices(actions: Any, envs: int, names: tuple[str, ...] | list[str]) -> NDArray[
        np.int64]:
    """A batch's ``Discrete(len(names))`` actions: an int array (or list of ints) of shape
    ``(envs,)`` with every value in range, as int64; bools, floats and other shapes are
    refused naming the expected shape and dtype."""
    count = len(names)
    array = actions if isinstance(actions, np.ndarray) else None
    if array is None and not isinstance(actions, str | bytes):
        try:
            array = np.asarray(actions)
        except (ValueError, TypeError):
            array = None
    if array is None or array.dtype.kind not in "iu" or array.shape != (envs,):
        got = (f"dtype {array.dtype} with shape {array.shape}" if array is not None
               else repr(actions))
        raise ValueError(f"actions must be an int array of shape ({envs},): one "
                         f"Discrete({count}) index per env in 0..{count - 1} = {list(names)};"
                         f" got {got}")
    bad = np.flatnonzero((array < 0) | (array >= count))
    if len(bad):
        raise ValueError(f"action {int(array[bad[0]])} of env {int(bad[0])} out of range; "
                         f"valid: 0..{count - 1} = {list(names)}")
    return array.astype(np.int64, copy=False)
