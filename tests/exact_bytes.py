"""Exact bytes of what an env returns, to compare two runs bit for bit."""

from __future__ import annotations

import struct
from typing import Any

import numpy as np


def feed_bytes(parts: list[bytes], value: Any) -> None:
    """``value`` as bytes, exactly: numeric arrays by dtype, shape and bytes, floats by
    their bits, dicts by sorted key, object arrays (the vector info's lists and dicts)
    item by item (their own bytes are pointers)."""
    if isinstance(value, np.ndarray) and value.dtype != object:
        parts += [f"{value.dtype}{value.shape}".encode(), np.ascontiguousarray(value).tobytes()]
    elif isinstance(value, np.ndarray):
        parts.append(f"object{value.shape}".encode())
        feed_bytes(parts, value.ravel().tolist())
    elif isinstance(value, dict):
        for key in sorted(value):
            parts.append(f"<{key}>".encode())
            feed_bytes(parts, value[key])
    elif isinstance(value, list | tuple):
        parts.append(b"[")
        for item in value:
            feed_bytes(parts, item)
        parts.append(b"]")
    elif isinstance(value, float | np.floating):
        parts.append(struct.pack("<d", float(value)))
    else:  # bool, int, str, None
        parts.append(f"{type(value).__name__}:{value}".encode())
