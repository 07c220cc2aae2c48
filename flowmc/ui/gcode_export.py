"""Export G-code from the editor: which Path of the graph, run it (through the session, cached), write it atomically."""

from __future__ import annotations

from pathlib import Path

from flowmc.errors import GcodeError
from flowmc.motion.gcode_write import write_gcode
from flowmc.ui.session import EditorSession, RunRefused
from flowmc.ui.state import EditorState

__all__ = ["export_gcode", "path_source"]


def path_source(state: EditorState) -> tuple[str, str] | None:
    """(node, output) of the Path to export: the graph's first Path interface output, else the one
    selected node's first Path output, else the last Path output in run order."""
    plan = state.plan()
    for _item, src in (v for k, v in plan.iface_outputs.items() if v[0].type == "Path"):
        return src
    nodes = state.selected_nodes
    order = ([nodes[0]] if len(nodes) == 1 else []) + list(reversed(plan.order))
    for node_id in order:
        if node_id in plan.nodes:
            _ins, outs = plan.ports(node_id)
            for name, port in outs.items():
                if port.type == "Path":
                    return node_id, name
    return None


def export_gcode(session: EditorSession) -> tuple[Path, str]:
    """Write ``<graph stem>.ngc`` beside the graph; returns the file and its text. GcodeError/GraphError say why not."""
    state = session.state
    with session.lock:
        issues = state.plan().issues
        if issues:
            raise GcodeError(f"the graph cannot run yet: {issues[0].message}", where="export")
        source = path_source(state)
    if source is None:
        raise GcodeError("the graph has no Path output to write", where="export")
    request = session.run(source="export")
    if isinstance(request, RunRefused):  # edited in between
        raise GcodeError(request.message, where="export")
    result = request.wait()
    if result is None:
        raise GcodeError(request.error or "the run was replaced by a newer one; export again", where="export")
    node = result.nodes.get(source[0])
    if node is None or node.status not in ("done", "cached"):
        raise GcodeError((node.error if node else None) or f"node {source[0]!r} did not run", where="export")
    stem = state.path.name[: -len(".flowmc.json")] if state.path is not None and state.path.name.endswith(".flowmc.json") \
        else Path(state.suggested_name).name.split(".")[0]
    target = state.base_dir / f"{stem}.ngc"
    write_gcode(node.outputs[source[1]], target, comment=f"flowmc {stem}: {source[0]}.{source[1]}")
    return target, target.read_text(encoding="utf-8")
