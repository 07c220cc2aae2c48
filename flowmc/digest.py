"""Content digests of values on wires: the runtime's cache keys are built from them.

Type-tagged, so ``1``, ``1.0``, ``True`` and ``"1"`` all differ; floats hash by ``repr``
so NaN is a stable key (not an always-miss) and ``-0.0`` differs from ``0.0``.
"""

from __future__ import annotations

import hashlib
import sys
from typing import Any

from pydantic import BaseModel

__all__ = ["digest", "Undigestable"]


class Undigestable(TypeError):
    """A value with no content digest: value types must define ``digest() -> str``."""


def digest(value: Any) -> str:
    """Hex content hash of ``value`` (None, scalars, containers, numpy arrays, models, ``digest()``-ables)."""
    h = hashlib.blake2b(digest_size=16)
    _feed(h, value)
    return h.hexdigest()


def _feed(h: Any, value: Any) -> None:
    if value is None:
        h.update(b"N;")
    elif value is True or value is False:
        h.update(b"T;" if value else b"F;")
    elif isinstance(value, int):
        h.update(b"i%d;" % value)
    elif isinstance(value, float):
        h.update(b"f" + repr(value).encode() + b";")
    elif isinstance(value, str):
        data = value.encode()
        h.update(b"s%d:" % len(data) + data)
    elif isinstance(value, (list, tuple)):
        h.update(b"l%d[" % len(value) if isinstance(value, list) else b"t%d[" % len(value))
        for item in value:
            _feed(h, item)
        h.update(b"]")
    elif isinstance(value, dict):
        h.update(b"d%d{" % len(value))
        for key in sorted(value, key=repr):
            _feed(h, key)
            _feed(h, value[key])
        h.update(b"}")
    elif _is_numpy(value):
        _feed_array(h, value)
    elif isinstance(value, BaseModel):
        h.update(b"m" + type(value).__qualname__.encode() + b":")
        _feed(h, value.model_dump_json())
    elif callable(getattr(value, "digest", None)):
        h.update(b"o" + type(value).__qualname__.encode() + b":")
        _feed(h, value.digest())
    else:
        raise Undigestable(f"a {type(value).__name__} has no content digest (value types must define digest())")


def _is_numpy(value: Any) -> bool:
    """A numpy array or scalar; asked without importing numpy (none exists before it is imported)."""
    np = sys.modules.get("numpy")
    return np is not None and isinstance(value, (np.ndarray, np.generic))


def _feed_array(h: Any, value: Any) -> None:
    import numpy as np

    array = np.asarray(value)
    if array.dtype == object:
        h.update(b"A" + repr(array.shape).encode() + b"[")
        for item in array.ravel():
            _feed(h, item)
        h.update(b"]")
        return
    h.update(b"a" + array.dtype.str.encode() + repr(array.shape).encode() + b":")
    h.update(np.ascontiguousarray(array).tobytes())
