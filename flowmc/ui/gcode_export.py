"""Export G-code from the editor: which Path of the graph, run it (through the session, cached), write it
atomically; never over a file the graph reads, and the editor asks before replacing any other."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from flowmc.errors import GcodeError
from flowmc.motion.gcode_write import write_gcode
from flowmc.runtime.context import files_read
from flowmc.ui.session import EditorSession, RunRefused
from flowmc.ui.state import EditorState

__all__ = ["Export", "prepare_export", "path_source"]


def path_source(state: EditorState) -> tuple[str, str] | None:
    """(node, output) of the Path to export: the graph's first Path interface output, else the one
    selected node's first Path output, else the last Path output in run order."""
    plan = state.plan()
    for _item, src in (v for k, v in plan.iface_outputs.items() if v[0].type == "Path"):
        return src
    found = plan.outputs_of("Path")
    nodes = state.selected_nodes
    for node_id in ([nodes[0]] if len(nodes) == 1 else []) + ([found[-1][0]] if found else []):
        for source in found:
            if source[0] == node_id:
                return source
    return None


@dataclass(frozen=True)
class Export:
    """A Path ready to write as G-code to ``target``: ``replaces`` says a file of that name exists (the
    editor asks before replacing it)."""

    target: Path
    path: Any
    comment: str

    @property
    def replaces(self) -> bool:
        return self.target.is_file() or self.target.is_symlink()

    def write(self) -> str:
        """Write the file atomically; returns its text."""
        return write_gcode(self.path, self.target, comment=self.comment)


def prepare_export(session: EditorSession) -> Export:
    """Run the graph (cached) for its Path and choose ``<graph stem>.ngc`` beside the graph. GcodeError/
    GraphError say why not, and a file the graph reads (its own G-code source) is never the target."""
    state = session.state
    with session.lock:
        plan = state.plan()
        if plan.issues:
            raise GcodeError(f"the graph cannot run yet: {plan.issues[0].message}", where="export")
        source = path_source(state)
    if source is None:
        raise GcodeError("the graph has no Path output to write", where="export")
    stem = state.path.name[: -len(".flowmc.json")] if state.path is not None and state.path.name.endswith(".flowmc.json") \
        else Path(state.suggested_name).name.split(".")[0]
    target = state.base_dir / f"{stem}.ngc"
    if target.resolve() in files_read(plan):
        raise GcodeError(f"{target.name} is a file this graph reads; save the graph under another name to "
                         "export beside it", where="export")
    request = session.run(source="export")
    if isinstance(request, RunRefused):  # edited in between
        raise GcodeError(request.message, where="export")
    result = request.wait()
    if result is None:
        raise GcodeError(request.error or "the run was replaced by a newer one; export again", where="export")
    node = result.nodes.get(source[0])
    if node is None or node.status not in ("done", "cached"):
        raise GcodeError((node.error if node else None) or f"node {source[0]!r} did not run", where="export")
    return Export(target, node.outputs[source[1]], f"flowmc {stem}: {source[0]}.{source[1]}")
