"""Copy and paste of graph pieces: nodes with their params and the wires between them, plus comments
and labels, as a small JSON fragment. The editor keeps the last copy for every graph it opens (so
a piece moves between files), and puts the same text on the browser's clipboard, so it also pastes
into another editor.

Pasting gives every node and note a fresh id where its own is taken, keeps the wires between the
pasted nodes (wires to nodes outside the piece are not copied), and moves the piece so that its
top-left corner lands at the given point.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

from flowmc.errors import GraphError
from flowmc.graph import Comment, Graph, Label, Node, Wire, split_ref
from flowmc.ui.extract import fresh_id

__all__ = ["FRAGMENT_KIND", "copy", "parse", "paste"]

FRAGMENT_KIND = "flowmc-fragment/1"
MAX_FRAGMENT = 5_000_000  # characters: a pasted text longer than this is not read


def copy(graph: Graph, node_ids: Sequence[str], note_ids: Sequence[str] = ()) -> str:
    """The fragment text of ``node_ids`` (with the wires between them) and the comments and labels ``note_ids``."""
    chosen = set(node_ids)
    notes = set(note_ids)
    data = {
        "kind": FRAGMENT_KIND,
        "nodes": [n.model_dump(mode="json") for n in graph.nodes if n.id in chosen],
        "wires": [w.model_dump(mode="json", by_alias=True) for w in graph.wires
                  if split_ref(w.from_)[0] in chosen and split_ref(w.to)[0] in chosen],
        "comments": [c.model_dump(mode="json") for c in graph.view.comments if c.id in notes],
        "labels": [lb.model_dump(mode="json") for lb in graph.view.labels if lb.id in notes],
    }
    return json.dumps(data, separators=(",", ":"))


def parse(text: str) -> dict[str, Any] | None:
    """The fragment in ``text``, or None when it is not one (any other clipboard text)."""
    if not isinstance(text, str) or len(text) > MAX_FRAGMENT or FRAGMENT_KIND not in text[:200]:
        return None
    try:
        data = json.loads(text)
        if data.get("kind") != FRAGMENT_KIND:
            return None
        nodes = [Node.model_validate(n) for n in data.get("nodes", [])]
        wires = [Wire.model_validate(w) for w in data.get("wires", [])]
        comments = [Comment.model_validate(c) for c in data.get("comments", [])]
        labels = [Label.model_validate(lb) for lb in data.get("labels", [])]
    except (ValueError, TypeError, AttributeError):
        return None
    return {"nodes": nodes, "wires": wires, "comments": comments, "labels": labels}


def paste(graph: Graph, fragment: dict[str, Any], at: tuple[float, float]) -> tuple[list[str], list[str]]:
    """Add a parsed fragment to ``graph`` with its top-left corner at ``at`` (canvas px); returns the new
    node ids and note ids."""
    nodes, comments, labels = fragment["nodes"], fragment["comments"], fragment["labels"]
    corners = [n.pos for n in nodes] + [c.pos for c in comments] + [lb.pos for lb in labels]
    if not corners:
        raise GraphError("the clipboard holds nothing to paste", where="paste")
    dx, dy = at[0] - min(p[0] for p in corners), at[1] - min(p[1] for p in corners)
    used = {n.id for n in graph.nodes}
    new_ids: dict[str, str] = {}
    for node in nodes:
        new_id = node.id if node.id not in used else fresh_id(node.id.rstrip("0123456789") or "node", used)
        used.add(new_id)
        new_ids[node.id] = new_id
        graph.nodes.append(Node(id=new_id, type=node.type, params=json.loads(json.dumps(node.params)),
                                pos=(round(node.pos[0] + dx, 1), round(node.pos[1] + dy, 1))))
    for wire in fragment["wires"]:
        (sn, sp), (dn, dp) = split_ref(wire.from_), split_ref(wire.to)
        if sn in new_ids and dn in new_ids:
            graph.wires.append(Wire(**{"from": f"{new_ids[sn]}.{sp}", "to": f"{new_ids[dn]}.{dp}"}))
    taken = {c.id for c in graph.view.comments} | {lb.id for lb in graph.view.labels}
    notes = []
    for note in [*comments, *labels]:
        note_id = note.id if note.id not in taken else fresh_id(note.id.rstrip("0123456789") or "note", taken)
        taken.add(note_id)
        moved = note.model_copy(update={"id": note_id, "pos": (round(note.pos[0] + dx, 1), round(note.pos[1] + dy, 1))})
        (graph.view.comments if isinstance(note, Comment) else graph.view.labels).append(moved)
        notes.append(note_id)
    return list(new_ids.values()), notes
