"""Helpers shared by the value types: content digests and small JSON summaries of arrays."""

from __future__ import annotations

import hashlib

import numpy as np

__all__ = ["array_digest", "frozen_array"]


def frozen_array(values, dtype=float, ndim: int | None = None) -> np.ndarray:
    """A read-only contiguous copy, so a value cannot change under the runtime's cache."""
    arr = np.array(values, dtype=dtype, copy=True, order="C")
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"expected a {ndim}-d array, got shape {arr.shape}")
    arr.setflags(write=False)
    return arr


def array_digest(*parts) -> str:
    """SHA-256 over arrays (dtype, shape, bytes) and plain scalars/strings, in order."""
    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, np.ndarray):
            h.update(f"{part.dtype.str}{part.shape}".encode())
            h.update(np.ascontiguousarray(part).tobytes())
        else:
            h.update(repr(part).encode())
        h.update(b"\x00")
    return h.hexdigest()
