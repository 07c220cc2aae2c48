"""The editor's document: one graph, its file, the selection, undo/redo. Plain Python, no viser.

Every edit the canvas and the inspector make goes through an ``EditorState`` method, so the
rules (what may be wired to what, what a delete takes with it) are tested without a browser.
Undo keeps whole-graph snapshots (``history``).
Listeners hear ``"graph"`` (content changed), ``"move"`` (positions only), ``"view"`` (comments and
labels), ``"selection"`` and ``"document"`` (another file, or saved).

What the canvas places has one key each: a node's id, an interface terminal's ``@in:<name>`` or
``@out:<name>``, and a comment's or label's ``#<id>``. ``selected_nodes`` holds nodes and
terminals, ``selected_notes`` comments and labels.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Iterable

from flowmc.api import Runtime
from flowmc.errors import GraphError
from flowmc.graph import Comment, Graph, Issue, Label, Node, Wire, dumps, load, loads, save, split_ref
from flowmc.ui import clipboard, extract, interface_edit, wiring
from flowmc.ui.extract import fresh_id
from flowmc.ui.history import History
from flowmc.ui.layout import terminal_of
from flowmc.ui.params import field_errors
from flowmc.ui.ports import NodePorts, node_ports

__all__ = ["EditorState", "UNSET", "WireKey"]

UNSET: Any = object()  # set_param(..., UNSET) removes a stored value (the default applies)
WireKey = tuple[str, str]  # (from "node.output", to "node.input")
MAX_UNDO = 200


def _toggled(chosen: list[Any], picked: list[Any]) -> list[Any]:
    """``chosen`` with each of ``picked`` taken out if it was in, else added."""
    out = list(chosen)
    for item in picked:
        if item in out:
            out.remove(item)
        else:
            out.append(item)
    return out


class EditorState:
    def __init__(self, graph: Graph | None = None, *, folder: str | Path | None = None, runtime: Runtime | None = None):
        self.runtime = runtime or Runtime()
        self.graph = Graph()
        self.folder = Path.cwd()
        self.selected_nodes: list[str] = []
        self.selected_wires: list[WireKey] = []
        self.selected_notes: list[str] = []
        self.suggested_name = "untitled.flowmc.json"
        self._listeners: list[Callable[[str], None]] = []
        self._plan: tuple[Any, ...] | None = None
        self._dirty: tuple[int, bool] | None = None
        self.revision = 0  # bumped by every change to the document (not by selection)
        self._stack: list[tuple] = []
        self._folder_set = False
        self._set_document(graph or Graph(), saved=graph is not None and graph.path is not None, folder=folder)

    # ------------------------------------------------------------ document
    @classmethod
    def open(cls, path: str | Path, runtime: Runtime | None = None) -> "EditorState":
        return cls(load(path), runtime=runtime)

    @property
    def path(self) -> Path | None:
        return self.graph.path

    @property
    def base_dir(self) -> Path:
        """Where the graph's relative file params (sub-graphs, pictures) are looked up."""
        return self.graph.path.parent if self.graph.path is not None else self.folder

    @property
    def dirty(self) -> bool:
        if self._dirty is None or self._dirty[0] != self.revision:
            try:
                text = dumps(self.graph)
            except GraphError:
                text = None
            self._dirty = (self.revision, text is None or text != self._saved)
        return self._dirty[1]

    def _set_document(self, graph: Graph, *, saved: bool, folder: str | Path | None = None) -> None:
        """Show ``graph``. The editor's folder is set once, when it starts (the given folder, else the first
        graph's); opening another file (an example elsewhere, a sub-graph) keeps it."""
        self.graph = graph
        if folder is not None or (graph.path is not None and not self._folder_set):
            self.folder = Path(folder).resolve() if folder is not None else graph.path.resolve().parent
            self._folder_set = True
        self._saved = dumps(graph) if saved else None
        self.history = History(MAX_UNDO)
        self.selected_nodes, self.selected_wires, self.selected_notes = [], [], []
        self._plan = None
        self._emit("document")

    def load(self, path: str | Path) -> None:
        """Open another graph file (GraphError when it cannot be read; the current one stays)."""
        self._set_document(load(path), saved=True)

    def load_text(self, text: str, name: str) -> None:
        """A graph from uploaded text; it has no file until saved (``suggested_name`` is its name)."""
        graph = loads(text, where=name)
        self.suggested_name = Path(name).name
        self._set_document(graph, saved=False)

    def save(self, path: str | Path | None = None) -> Path:
        """Save atomically (flowmc's canonical save) to ``path`` or the graph's own file."""
        target = Path(path) if path is not None else self.graph.path
        if target is None:
            raise GraphError("the graph has no file yet: use Save as", where=self.suggested_name)
        save(self.graph, target)
        self._saved = dumps(self.graph)
        self._dirty = None
        self._emit("document")
        return target

    # ------------------------------------------------------------ listeners and history
    def subscribe(self, listener: Callable[[str], None]) -> Callable[[], None]:
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    def _emit(self, kind: str) -> None:
        if kind != "selection":
            self.revision += 1
        for listener in tuple(self._listeners):
            listener(kind)

    def record(self) -> None:
        """Snapshot the graph before an edit (edits call this; a drag calls it once at its start)."""
        self.history.record(self.graph)

    @property
    def can_undo(self) -> bool:
        return self.history.can_undo

    @property
    def can_redo(self) -> bool:
        return self.history.can_redo

    def undo(self) -> bool:
        return self._restore(self.history.undo(self.graph))

    def redo(self) -> bool:
        return self._restore(self.history.redo(self.graph))

    def _restore(self, snapshot: Graph | None) -> bool:
        if snapshot is None:
            return False
        self.graph = snapshot
        self.selected_nodes = [n for n in self.selected_nodes if self.has_item(n)]
        self.selected_wires = [w for w in self.selected_wires if w in set(self.wire_keys())]
        self.selected_notes = [n for n in self.selected_notes if self.has_item(n)]
        self._emit("graph")
        return True

    # ------------------------------------------------------------ looking things up
    def node(self, node_id: str) -> Node:
        return self.graph.node(node_id)

    def has_node(self, node_id: str) -> bool:
        return any(n.id == node_id for n in self.graph.nodes)

    def has_item(self, key: str) -> bool:
        """A node, an interface terminal (``@in:x``) or a comment or label (``#id``) with this key."""
        if key.startswith("#"):
            return self.note(key) is not None
        term = terminal_of(key)
        if term is not None:
            iface = self.graph.interface
            return iface is not None and term[1] in {i.name for i in (iface.inputs if term[0] == "in" else iface.outputs)}
        return self.has_node(key)

    def note(self, key: str) -> Comment | Label | None:
        """The comment or label ``#id`` (None when there is none)."""
        note_id = key[1:]
        comment = next((c for c in self.graph.view.comments if c.id == note_id), None)
        return comment if comment is not None else next((lb for lb in self.graph.view.labels if lb.id == note_id), None)

    def wire_keys(self) -> list[WireKey]:
        """Every wire the canvas draws: node wires, then interface terminal wires."""
        return [(w.from_, w.to) for w in self.graph.wires] + [(a, b) for a, b, _ in interface_edit.terminal_wires(self.graph)]

    def plan(self) -> Any:
        """The runtime's plan of the current graph (validated; remembered until the graph changes)."""
        memo = self._plan
        if memo is not None and memo[0] == self.revision and memo[2].deps_unchanged():
            return memo[2]
        key = self.graph.fingerprint_json() + "|" + str(self.base_dir)
        if memo is None or memo[1] != key or not memo[2].deps_unchanged():
            memo = (self.revision, key, self.runtime.plan(self.graph, base_dir=self.base_dir))
        self._plan = (self.revision, key, memo[2])
        return memo[2]

    def issues(self) -> list[Issue]:
        return list(self.plan().issues)

    def ports(self, node_id: str) -> NodePorts:
        return node_ports(self.node(node_id), self.runtime.registry, self.base_dir, self.plan())

    def param_errors(self, node_id: str) -> dict[tuple, str]:
        """Problems with the node's stored params, by field path (params fed by a wire are skipped)."""
        node = self.node(node_id)
        try:
            cls = self.runtime.registry.lookup(node.type, self.base_dir)
        except GraphError as exc:
            return {("(type)",): exc.message}
        wired = {split_ref(w.to)[1] for w in self.graph.wires if split_ref(w.to)[0] == node_id}
        return field_errors(cls.Params, node.params, skip=wired)

    # ------------------------------------------------------------ edits
    def add_node(self, type_id: str, pos: tuple[float, float] = (0.0, 0.0), params: dict[str, Any] | None = None) -> str:
        """Add a node with a fresh id (from the type's name, or a sub-graph's file name)."""
        params = dict(params or {})
        from_file = type_id == "subgraph" and params.get("file")
        stem = Path(str(params["file"])).name.split(".")[0] if from_file else type_id.rsplit(".", 1)[-1]
        node_id = fresh_id(stem, {n.id for n in self.graph.nodes})
        self.record()
        self.graph.nodes.append(Node(id=node_id, type=type_id, params=params, pos=(float(pos[0]), float(pos[1]))))
        self._emit("graph")
        return node_id

    def move_nodes(self, positions: dict[str, tuple[float, float]], record: bool = True) -> None:
        """Place nodes, terminals and notes by key (canvas pixels, top-left); a drag records once at its
        start and passes ``record=False``."""
        if record:
            self.record()
        for key, (x, y) in positions.items():
            pos = (round(float(x), 1), round(float(y), 1))
            term = terminal_of(key)
            if key.startswith("#"):
                note = self.note(key)
                if note is not None:
                    note.pos = pos
            elif term is not None:
                self.graph.view.terminals[f"{term[0]}.{term[1]}"] = pos
            else:
                self.node(key).pos = pos
        self._emit("move")

    def move_node(self, node_id: str, pos: tuple[float, float], record: bool = True) -> None:
        self.move_nodes({node_id: pos}, record)

    def delete(self, nodes: Iterable[str] = (), wires: Iterable[WireKey] = (), notes: Iterable[str] = ()) -> bool:
        """Delete nodes (with their wires and the interface outputs they fed), interface terminals,
        wires (terminal wires too) and comments or labels; False when nothing matched."""
        keys, cut, dropped = set(nodes), set(wires), {n[1:] for n in notes}
        terms = [t for t in map(terminal_of, keys) if t is not None]
        gone = {k for k in keys if terminal_of(k) is None}
        keep_wires = [w for w in self.graph.wires if (w.from_, w.to) not in cut
                      and split_ref(w.from_)[0] not in gone and split_ref(w.to)[0] not in gone]
        keep_nodes = [n for n in self.graph.nodes if n.id not in gone]
        view = self.graph.view
        keep_notes = ([c for c in view.comments if c.id not in dropped], [lb for lb in view.labels if lb.id not in dropped])
        cut_terminal = [w for w in cut if w in set(self.wire_keys()) and (w[0].startswith("@") or w[1].startswith("@"))]
        if (len(keep_wires) == len(self.graph.wires) and len(keep_nodes) == len(self.graph.nodes) and not terms
                and not cut_terminal and len(keep_notes[0]) + len(keep_notes[1]) == len(view.comments) + len(view.labels)):
            return False
        self.record()
        self.graph.nodes, self.graph.wires = keep_nodes, keep_wires
        view.comments, view.labels = keep_notes
        extract.drop_interface_refs(self.graph, gone)
        for src, dst in cut_terminal:
            if src.startswith("@in:"):
                interface_edit.unfeed(self.graph, src[4:], dst)
            else:
                interface_edit.remove(self.graph, "out", dst[5:])
        for kind, name in terms:
            interface_edit.remove(self.graph, kind, name)
        self.selected_nodes = [n for n in self.selected_nodes if n not in keys]
        self.selected_wires = [w for w in self.selected_wires if w not in cut and not {split_ref(x)[0] for x in w} & gone]
        self.selected_notes = [n for n in self.selected_notes if n[1:] not in dropped]
        self._emit("graph")
        return True

    def delete_selection(self) -> bool:
        return self.delete(self.selected_nodes, self.selected_wires, self.selected_notes)

    def disconnect(self, wire: WireKey) -> bool:
        return self.delete(wires=[wire])

    def connect(self, src: str, dst: str) -> str | None:
        """Wire output ``src`` ("node.output") to input ``dst`` ("node.input" or a scalar param).
        Returns why it is refused (``wiring.refusal``), or None when wired; a wire already feeding
        ``dst`` is replaced."""
        if src.startswith("@") or dst.startswith("@"):
            return self._connect_terminal(src, dst)
        reason = wiring.refusal(self.graph, self.ports, src, dst)
        if reason is not None:
            return reason
        self.record()
        self.graph.wires = [w for w in self.graph.wires if w.to != dst] + [Wire(**{"from": src, "to": dst})]
        self._emit("graph")
        return None

    def _connect_terminal(self, src: str, dst: str) -> str | None:
        """A wire from an interface input terminal (``@in:x``) or into an output terminal (``@out:x``)."""
        reason = wiring.terminal_refusal(self.graph, self.ports, src, dst)
        if reason is not None:
            return reason
        self.record()
        if src.startswith("@in:"):
            interface_edit.feed(self.graph, src[4:], dst)
        else:
            interface_edit.take_from(self.graph, dst[5:], src)
        self._emit("graph")
        return None

    def set_param(self, node_id: str, name: str, value: Any) -> dict[tuple, str]:
        """Store a param value (``UNSET`` removes it) and return the node's param problems by field.
        Invalid values are kept, so what the form shows is what the file holds; validation then
        refuses to run the graph and names the field. Wires to ports the change removed are dropped."""
        node = self.node(node_id)
        if node.params.get(name, UNSET) is value or (name in node.params and node.params[name] == value):
            return self.param_errors(node_id)
        self.record()
        if value is UNSET:
            node.params.pop(name, None)
        else:
            node.params[name] = value
        self._drop_dangling_wires(node_id)
        self._emit("graph")
        return self.param_errors(node_id)

    def _drop_dangling_wires(self, node_id: str) -> None:
        """After a param change: wires to ports the node no longer has go (only when its new ports are known)."""
        self._plan = None  # the remembered plan is of the graph before the change
        plan = self.plan()
        if node_id not in plan.nodes:
            return
        ports = self.ports(node_id)
        names_in = {p.name for p in ports.inputs}
        names_out = {p.name for p in ports.outputs}

        def keep(w: Wire) -> bool:
            (sn, sp), (dn, dp) = split_ref(w.from_), split_ref(w.to)
            return not ((sn == node_id and sp not in names_out) or (dn == node_id and dp not in names_in))

        self.graph.wires = [w for w in self.graph.wires if keep(w)]

    # ------------------------------------------------------------ selection
    def select(self, nodes: Iterable[str] = (), wires: Iterable[WireKey] = (), notes: Iterable[str] = (), *,
               toggle: bool = False) -> None:
        """Select exactly these (``toggle``: add them to the selection, or take them out if selected)."""
        nodes = [n for n in nodes if self.has_item(n) and not n.startswith("#")]
        wires, notes = list(wires), [n for n in notes if self.has_item(n)]
        if toggle:
            self.selected_nodes = _toggled(self.selected_nodes, nodes)
            self.selected_wires = _toggled(self.selected_wires, wires)
            self.selected_notes = _toggled(self.selected_notes, notes)
        else:
            self.selected_nodes, self.selected_wires, self.selected_notes = nodes, wires, notes
        self._emit("selection")

    def clear_selection(self) -> None:
        if self.selected_nodes or self.selected_wires or self.selected_notes:
            self.select()

    # ------------------------------------------------------------ comments and labels (view state)
    def add_note(self, kind: str, text: str, pos: tuple[float, float], size: tuple[float, float] | None = None) -> str:
        """A comment box (``kind`` "comment", ``size`` in px) or a free label at ``pos``; returns its key ``#id``."""
        view = self.graph.view
        note_id = fresh_id(kind, {c.id for c in view.comments} | {lb.id for lb in view.labels})
        self.record()
        pos = (round(float(pos[0]), 1), round(float(pos[1]), 1))
        if kind == "comment":
            view.comments.append(Comment(id=note_id, text=text, pos=pos, size=size or (320.0, 200.0)))
        else:
            view.labels.append(Label(id=note_id, text=text, pos=pos))
        self._emit("view")
        return f"#{note_id}"

    def set_note(self, key: str, *, text: str | None = None, size: tuple[float, float] | None = None) -> None:
        """Change a note's text, or a comment's size (px)."""
        note = self.note(key)
        if note is None:
            raise GraphError(f"no comment or label {key[1:]!r}", where=str(self.path or self.suggested_name))
        if (text is None or note.text == text) and (size is None or getattr(note, "size", None) == size):
            return
        self.record()
        if text is not None:
            note.text = text
        if size is not None and isinstance(note, Comment):
            note.size = (round(max(float(size[0]), 80.0), 1), round(max(float(size[1]), 60.0), 1))
        self._emit("view")

    # ------------------------------------------------------------ copy and paste
    def copy_selection(self) -> str | None:
        """The selection as clipboard text (nodes, the wires between them, comments, labels); None when empty."""
        nodes = [n for n in self.selected_nodes if terminal_of(n) is None]
        if not nodes and not self.selected_notes:
            return None
        return clipboard.copy(self.graph, nodes, [n[1:] for n in self.selected_notes])

    def paste(self, text: str, at: tuple[float, float]) -> list[str]:
        """Paste clipboard text at ``at`` (canvas px, top-left) and select what came; GraphError when the
        text is not a piece of a graph."""
        fragment = clipboard.parse(text)
        if fragment is None:
            raise GraphError("the clipboard holds no flowmc nodes", where="paste")
        self.record()
        nodes, notes = clipboard.paste(self.graph, fragment, at)
        self.selected_nodes, self.selected_wires, self.selected_notes = nodes, [], [f"#{n}" for n in notes]
        self._emit("graph")
        return nodes

    # ------------------------------------------------------------ the interface, as terminals
    def add_terminal(self, kind: str, name: str, port_type: str = "", source: str = "", description: str = "") -> str:
        """A new interface input (``kind`` "in", of ``port_type``) or output (``kind`` "out", from ``source``);
        returns its terminal key. GraphError says why not."""
        if kind == "out":
            node_id, port = split_ref(source)
            out = self.ports(node_id).output(port) if self.has_node(node_id) else None
            if out is None:
                raise GraphError(f"{source!r} is not a node output", where="interface")
            port_type = out.type
        graph = self.graph.model_copy(deep=True)
        graph.path = self.graph.path
        reason = (interface_edit.add_input(graph, name, port_type, description) if kind == "in"
                  else interface_edit.add_output(graph, name, source, port_type, description))
        if reason is not None:
            raise GraphError(reason, where="interface")
        self.record()
        self.graph = graph
        self._emit("graph")
        return f"@{kind}:{name}"

    def rename_terminal(self, key: str, new: str) -> None:
        kind, old = terminal_of(key) or ("", "")
        graph = self.graph.model_copy(deep=True)
        graph.path = self.graph.path
        reason = interface_edit.rename(graph, kind, old, new)
        if reason is not None:
            raise GraphError(reason, where="interface")
        self.record()
        self.graph = graph
        self.selected_nodes = [f"@{kind}:{new}" if n == key else n for n in self.selected_nodes]
        self._emit("graph")

    # ------------------------------------------------------------ sub-graphs
    def subgraph_file(self, node_id: str) -> Path | None:
        """The file a ``subgraph`` or ``lib.*`` node runs (None for other nodes)."""
        return extract.node_file(self.node(node_id), self.base_dir)

    def enter(self, path: Path) -> None:
        """Edit a sub-graph's file; the open graph (unsaved changes and undo included) waits on a stack."""
        graph = load(path)
        self._stack.append((self.graph, self._saved, self.history, self.selected_nodes))
        self._set_document(graph, saved=True)

    def leave(self) -> None:
        """Back to the graph that opened this sub-graph (GraphError when there are unsaved changes)."""
        if not self._stack:
            raise GraphError("this is not a sub-graph opened from another graph", where=str(self.path))
        if self.dirty:
            raise GraphError("unsaved changes: save or undo them first", where=str(self.path))
        graph, saved, history, selected = self._stack.pop()
        self._set_document(graph, saved=False)
        self._saved, self.history, self.selected_nodes = saved, history, selected
        self._emit("document")

    @property
    def waiting(self) -> list[Graph]:
        """The graphs waiting for the sub-graph being edited (with their unsaved changes), outermost first."""
        return [entry[0] for entry in self._stack]

    @property
    def parents(self) -> list[str]:
        """Names of the graphs waiting for a sub-graph being edited, outermost first."""
        return [entry[0].path.name if entry[0].path else "untitled" for entry in self._stack]

    def make_subgraph(self, node_ids: Iterable[str], file: str) -> str:
        """Move ``node_ids`` into a new graph file (``file``, relative to the graph's folder, written
        atomically); wires that crossed the selection become its interface. Returns the new node's id."""
        ids = [n for n in node_ids if self.has_node(n)]
        parent, child, target = extract.extract(self.graph, ids, file, self.base_dir, self.ports)
        self.record()
        save(child, target)
        self.graph.nodes, self.graph.wires, self.graph.interface = parent.nodes, parent.wires, parent.interface
        new_id = parent.nodes[-1].id
        self.selected_nodes, self.selected_wires = [new_id], []
        self._emit("graph")
        return new_id
