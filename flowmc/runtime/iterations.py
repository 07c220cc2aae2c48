"""Running a structure's body: once per loop iteration, or once for the case that is chosen.

A structure node (``flowmc.nodes.structures``) binds its bodies at plan time through the binding
protocol and, while it runs, hands each pass to a ``BodyRunner``. The runner owns what is the same
for every structure: the body runs on the node's child runtime (whose node cache serves the body's
nodes that do not change from pass to pass); a pure body's passes are cached by content (the body's
key and the digests of the values going in), so a loop run again with one more iteration runs only
that one; each pass of a loop is announced as an ``iteration`` event ("iteration 3 of 5"), loops
inside the body included (their node id is the path ``outer/inner``); and a failing pass becomes one
error that names it.
"""

from __future__ import annotations

import hashlib
from typing import Any, Mapping

from flowmc.digest import digest
from flowmc.errors import NodeError
from flowmc.runtime.cache import CacheEntry, signature
from flowmc.runtime.events import Event

__all__ = ["BodyRunner", "iteration_text"]


def iteration_text(k: int, count: int | None) -> str:
    """How a pass is named to people: ``iteration 3 of 5`` (1-based; a While loop: ``of at most``)."""
    return f"iteration {k} of {count}" if count is not None else f"iteration {k}"


class BodyRunner:
    """Runs one bound body of the structure node ``ctx`` belongs to, during one run of that node.

    Use it as a context manager: it forwards the iteration events of loops inside the body while it
    is open, and ends the cache generation when it closes."""

    def __init__(self, ctx: Any, plan: Any, key: str, *, runtime: Any = None, limit: int | None = None) -> None:
        self.ctx, self.plan = ctx, plan
        self.runtime = runtime if runtime is not None else ctx.child_runtime()
        self.limit = limit  # While loops: the most iterations there can be (events say "of at most")
        self.pure = bool(plan.pure)
        self._static = hashlib.blake2b(f"body\0{key}".encode(), digest_size=16).digest()
        self._unsubscribe: Any = None

    def __enter__(self) -> "BodyRunner":
        self.runtime.iterations.begin()
        node_id, announce = self.ctx.node_id, self.ctx.announce

        def forward(event: Event) -> None:
            if event.kind == "iteration":
                announce(Event("iteration", f"{node_id}/{event.node_id}", None, event.message, event.iteration))

        self._unsubscribe = self.runtime.subscribe(forward)
        return self

    def __exit__(self, exc_type: Any, *_exc: Any) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
        if exc_type is None:
            self.runtime.iterations.end()

    def iteration(self, k: int, count: int | None, inputs: Mapping[str, Any]) -> dict[str, Any]:
        """Pass ``k`` (1-based) of ``count`` (None: not known yet), announced before it runs."""
        text = iteration_text(k, count)
        if count is None and self.limit is not None:
            text += f" (at most {self.limit})"
        self.ctx.announce(Event("iteration", self.ctx.node_id, None, text, (k, count)))
        return self.run(inputs, text)

    def run(self, inputs: Mapping[str, Any], what: str) -> dict[str, Any]:
        """The body's interface outputs for these interface inputs (None values are left out: the
        body's own defaults apply). A failure raises NodeError starting with ``what``."""
        given = {name: value for name, value in inputs.items() if value is not None}
        sig = None
        if self.pure:
            sig = signature(self._static, sorted((name, digest(value)) for name, value in given.items()))
            entry = self.runtime.iterations.get(sig)
            if entry is not None:
                return dict(entry.outputs)
        result = self.runtime.run(self.plan, given)
        if not result.ok:
            raise NodeError(f"{what}: {'; '.join(result.errors)}")
        outputs = dict(result.outputs)
        if sig is not None:
            self.runtime.iterations.put(CacheEntry(sig, outputs, {}))
        return outputs
