"""Output cache of pure nodes, keyed by a content signature.

signature = hash(type id, type version, canonical params, the digests of the values on the
node's wired inputs). The static part is hashed once per plan; a run only adds input digests.
One entry per node id (its last result), so memory stays bounded in a long editor session.
"""

from __future__ import annotations

import hashlib
from typing import Any, Iterable

__all__ = ["static_key", "signature", "CacheEntry", "NodeCache", "IterationCache"]


def static_key(type_id: str, version: int, params_json: str, extra: str = "") -> bytes:
    """The part of a signature that depends only on the graph (computed once per plan)."""
    text = f"{type_id}\0{version}\0{params_json}\0{extra}"
    return hashlib.blake2b(text.encode(), digest_size=16).digest()


def signature(static: bytes, input_digests: Iterable[tuple[str, str]]) -> bytes:
    """Combine the static key with ``(port, digest)`` pairs of the inputs (in port order)."""
    h = hashlib.blake2b(static, digest_size=16)
    for port, value_digest in input_digests:
        h.update(port.encode())
        h.update(b"=")
        h.update(value_digest.encode())
        h.update(b";")
    return h.digest()


class CacheEntry:
    """One cached run: the signature it ran under, its outputs and their digests (a plain class: a
    dataclass's methods are compiled from text at every start)."""

    __slots__ = ("signature", "outputs", "digests")

    def __init__(self, signature: bytes, outputs: dict[str, Any], digests: dict[str, str]) -> None:
        self.signature = signature
        self.outputs = outputs
        self.digests = digests


class NodeCache:
    def __init__(self) -> None:
        self._entries: dict[str, CacheEntry] = {}

    def get(self, node_id: str, sig: bytes) -> CacheEntry | None:
        entry = self._entries.get(node_id)
        return entry if entry is not None and entry.signature == sig else None

    def put(self, node_id: str, entry: CacheEntry) -> None:
        self._entries[node_id] = entry

    def drop(self, node_id: str) -> None:
        self._entries.pop(node_id, None)

    def clear(self) -> None:
        self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)


class IterationCache:
    """A structure body's runs by content signature (one per loop iteration, one per case).

    Each run of the structure is a generation: what it looks up or stores is kept for the next run, the
    rest is dropped at ``end()``, so memory stays bounded by one run's iterations, as ``NodeCache`` is by
    one entry per node."""

    def __init__(self) -> None:
        self._now: dict[bytes, CacheEntry] = {}
        self._last: dict[bytes, CacheEntry] = {}

    def begin(self) -> None:
        self._last, self._now = {**self._last, **self._now}, {}

    def end(self) -> None:
        self._last = {}

    def get(self, sig: bytes) -> CacheEntry | None:
        entry = self._now.get(sig)
        if entry is None:
            entry = self._last.pop(sig, None)
            if entry is not None:
                self._now[sig] = entry
        return entry

    def put(self, entry: CacheEntry) -> None:
        self._now[entry.signature] = entry

    def clear(self) -> None:
        self._now.clear()
        self._last.clear()

    def __len__(self) -> int:
        return len(self._now) + len(self._last)
