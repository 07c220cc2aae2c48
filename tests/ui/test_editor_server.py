"""The real Editor on an ephemeral port, driven in-process through the same GUI handles the page uses
(setting a handle's value fires its callbacks, as a browser event does)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
import warnings
from pathlib import Path

import pytest

import flowmc
from editor_graphs import chain_file, example_file
from flowmc.devices.session import DeviceSession
from flowmc.ui import layout
from flowmc.ui.app import Editor
from flowmc.ui.examples import examples_dir
from flowmc.ui.text import unescape_md
from wire_client import messages_on_connect, page, send_value


@pytest.fixture
def editor(tmp_path, open_editor):
    return open_editor(example_file(tmp_path), extensions=False)


def click(editor, node_id, kind=None, port=None):
    """Click the middle of a node, or one of its ports, the way a click ray would land."""
    box = next(b for b in editor.canvas.boxes if b.node_id == node_id)
    spot = box.port(kind, port) if kind is not None else None
    got = editor.canvas.click(*box.centre) if spot is None else editor.canvas.click(spot.x, spot.y)
    return got


def page_event(editor, kind, data):
    """What the page script sends (``window.flowmc.send``): one new value of the hidden channel field."""
    page_event.n = getattr(page_event, "n", 0) + 1
    editor.channel.value = json.dumps({"kind": kind, "n": page_event.n, "data": data})


def run(editor):
    editor.run_button.value = True
    result = editor.wait()
    assert not editor.session.running
    return result


def test_opens_the_graph_and_runs_it_with_status_colours(editor):
    assert "example.flowmc.json" in unescape_md(editor.header.content) and "●" not in unescape_md(editor.header.content)
    ids = [b.node_id for b in editor.canvas.boxes]
    assert sorted(ids[:4]) == ["both", "edge", "shift", "table"] and ids[4] == "@out:path"  # and the output's terminal
    assert len(editor.canvas.curves) == 4 and ("both.path", "@out:path") in editor.canvas.curves
    result = run(editor)
    assert result.ok
    assert {n: s[0] for n, s in editor.canvas.status.items()} == dict.fromkeys(["table", "edge", "shift", "both"], "done")
    body = editor.canvas._handles["body"].batched_colors
    assert len({tuple(c) for c in body[:4]}) == 1  # every node the 'done' colour (the terminal is not a node)
    assert run(editor).cached == result.order  # the same runtime: everything cached
    assert {s[0] for s in editor.canvas.status.values()} == {"cached"}
    assert "cached" in editor.messages[-1][1]


def test_palette_adds_nodes_that_wire_and_run(editor):
    editor.palette.search.value = "translate"
    assert editor.palette.shown[0].key == "path.translate"
    assert 'data-flowmc-key="path.translate"' in editor.palette.list.content
    page_event(editor, "palette-add", {"key": "path.translate"})
    new = editor.state.selected_nodes[0]
    assert editor.state.node(new).type == "path.translate"
    assert editor.inspector.node_id == new and ("dx",) in editor.inspector.fields
    assert click(editor, "both", "out", "path").kind == "port"
    assert editor.canvas.pending is not None
    click(editor, new, "in", "path")
    assert ("both.path", f"{new}.path") in {(w.from_, w.to) for w in editor.state.graph.wires}
    assert run(editor).nodes[new].status == "done"
    count = len(editor.state.graph.nodes)
    for data in ({"key": "no.such"}, {"key": ["path.translate"]}, "path.translate", None):  # the page is not trusted
        page_event(editor, "palette-add", data)
    assert len(editor.state.graph.nodes) == count


def test_an_example_opens_from_its_listed_name_only(editor):
    for data in ({"key": "../example.flowmc.json"}, {"key": "nothing.flowmc.json"}, "thesis_3axis.flowmc.json"):
        page_event(editor, "example-open", data)
    assert editor.state.path.name == "example.flowmc.json"
    page_event(editor, "example-open", {"key": "thesis_3axis.flowmc.json"})
    assert editor.state.path.name == "thesis_3axis.flowmc.json"
    assert editor.state.path.parent == examples_dir()


def test_incompatible_wire_is_refused_with_a_message(editor):
    editor.palette.search.value = "add"
    page_event(editor, "palette-add", {"key": "basic.add"})
    adder = editor.state.selected_nodes[0]
    before = len(editor.state.graph.wires)
    click(editor, "shift", "out", "path")
    click(editor, adder, "in", "a")
    assert len(editor.state.graph.wires) == before
    kind, text = editor.messages[-1]
    assert kind == "error" and "Path" in text and "Number" in text
    click(editor, "table", "out", "path")
    click(editor, "edge", "out", "path")
    assert "both outputs" in editor.messages[-1][1]


def test_invalid_param_shows_at_the_field_and_stops_the_run(editor):
    click(editor, "table")
    assert editor.state.selected_nodes == ["table"]
    editor.inspector.fields[("feed",)].value = -4.0
    assert editor.inspector.errors[("feed",)].visible
    assert "greater than 0" in unescape_md(editor.inspector.errors[("feed",)].content)
    assert editor.run() is None
    assert editor.messages[-1][0] == "error" and "feed" in editor.messages[-1][1]
    assert "1 problem" in unescape_md(editor.problems.summary.content)
    click(editor, "edge")
    editor.problems.buttons[0].value = True  # the problem's button selects its node
    assert editor.state.selected_nodes == ["table"]
    editor.inspector.fields[("feed",)].value = 20.0
    assert not editor.inspector.errors[("feed",)].visible
    assert run(editor).ok


def test_segment_table_rows_are_a_grid_of_cells(editor):
    click(editor, "table")
    ins = editor.inspector
    grid_id = "table/rows"
    html = ins.fields[("rows",)].content
    for title in ("type", "end X (mm)", "radius (mm)", "start angle (deg)", "tool down"):
        assert f">{title}<" in html  # readable column titles with units
    assert ins.grid_event(grid_id, {"op": "set", "row": 1, "col": "radius", "value": "-2"}) is None
    problem = unescape_md(ins.errors[("rows",)].content)
    assert "row 2, radius: " in problem and "greater than 0" in problem and ins.errors[("rows",)].visible
    assert "#e03131" in ins.fields[("rows",)].content  # the bad cell is outlined
    ins.grid_event(grid_id, {"op": "set", "row": 1, "col": "radius", "value": "12"})
    assert not ins.errors[("rows",)].visible
    ins.fields[("rows", "add")].value = "line"
    rows = editor.state.node("table").params["rows"]
    assert len(rows) == 5 and rows[-1]["type"] == "line"
    ins.grid_event(grid_id, {"op": "set", "row": 4, "col": "end.1", "value": "6"})
    assert editor.state.node("table").params["rows"][4]["end"] == [0.0, 6.0, 0.0]
    assert "not a number" in ins.grid_event(grid_id, {"op": "set", "row": 4, "col": "end.0", "value": "x"})
    ins.grid_event(grid_id, {"op": "set", "row": 4, "col": "type", "value": "arc"})  # the row's kind
    assert set(editor.state.node("table").params["rows"][4]) >= {"type", "direction", "radius"}
    ins.grid_event(grid_id, {"op": "delete", "row": 4})
    assert len(editor.state.node("table").params["rows"]) == 4
    assert editor.state.node("table").params["rows"][1]["radius"] == 12.0
    assert "4 rows" in unescape_md(ins.fields[("rows", "count")].content)


def test_twenty_rows_paste_from_tab_separated_text(editor):
    click(editor, "table")
    lines = ["type\tend X (mm)\tend Y (mm)\tend Z (mm)"] + [f"line\t{10 * k}\t{5 * k}\t0" for k in range(19)]
    lines.append("arc\t\t\t")  # an arc: no end point; its own cells are further right
    assert editor.inspector.grid_event("table/rows", {"op": "paste", "row": 0, "col": "type", "text": "\n".join(lines)}) is None
    rows = editor.state.node("table").params["rows"]
    assert len(rows) == 20  # the header line was skipped; rows were added as needed
    assert rows[7] == {"type": "line", "end": [70.0, 35.0, 0.0]} and rows[19]["type"] == "arc"
    assert editor.inspector.grid_event("table/rows", {"op": "paste", "row": 19, "col": "radius", "text": "5\t0\t90"}) is None
    assert {"radius": 5.0, "start_angle": 0.0, "end_angle": 90.0}.items() <= editor.state.node("table").params["rows"][19].items()


def test_points_and_optional_numbers_are_text_fields(editor):
    click(editor, "edge")
    editor.inspector.fields[("points",)].value = "0, 0, 0\n10, 5, 0\n20, 0, 0"
    assert editor.state.node("edge").params["points"] == [[0, 0, 0], [10, 5, 0], [20, 0, 0]]
    editor.inspector.fields[("points",)].value = "0, 0, 0\n10, x, 0"
    assert "line 2" in unescape_md(editor.inspector.errors[("points",)].content)
    assert len(editor.state.node("edge").params["points"]) == 3  # not stored: it did not parse
    click(editor, "both")
    editor.inspector.fields[("rapid_feed",)].value = "25"
    assert editor.state.node("both").params["rapid_feed"] == 25
    editor.inspector.fields[("rapid_feed",)].value = ""
    assert editor.state.node("both").params["rapid_feed"] is None


def test_select_delete_undo_redo_and_fit(editor):
    wire = ("edge.path", "both.path2")
    curve = editor.canvas.curves[wire]
    mid = curve[len(curve) // 2]
    assert editor.canvas.click(mid[0], mid[1]).wire == wire
    assert editor.state.selected_wires == [wire]
    editor.edit_ops.value = "Delete"
    assert wire not in {(w.from_, w.to) for w in editor.state.graph.wires}
    click(editor, "edge")
    editor.canvas.click(*next(b for b in editor.canvas.boxes if b.node_id == "table").centre, toggle=True)
    assert editor.state.selected_nodes == ["edge", "table"]
    assert "2 nodes" in unescape_md(editor.selection.summary.content)
    editor.selection.delete_button.value = True
    assert not editor.state.has_node("edge") and "●" in unescape_md(editor.header.content)
    editor.edit_ops.value = "Undo"
    editor.edit_ops.value = "Undo"
    assert editor.state.has_node("edge") and wire in {(w.from_, w.to) for w in editor.state.graph.wires}
    editor.edit_ops.value = "Redo"
    assert wire not in {(w.from_, w.to) for w in editor.state.graph.wires}
    editor.canvas.click(-50.0, 50.0)
    assert editor.state.selected_nodes == []
    editor.edit_ops.value = "Fit"  # no clients: nothing to move, and no error
    assert editor.messages == [] or editor.messages[-1][0] != "error"


def test_files_save_save_as_open_upload_download_and_gcode(editor, tmp_path):
    files = editor.files
    editor.state.move_node("edge", (10, 300))
    assert "●" in unescape_md(editor.header.content)
    files.save_button.value = True
    assert "●" not in unescape_md(editor.header.content)
    assert flowmc.load(tmp_path / "example.flowmc.json").node("edge").pos == (10.0, 300.0)
    files.save_as_name.value = "copy"
    files.save_as_button.value = True
    assert editor.state.path == tmp_path / "copy.flowmc.json" and (tmp_path / "copy.flowmc.json").exists()
    assert "copy.flowmc.json" in files.open_choice.options
    files.save_as_name.value = "../escape"
    files.save_as_button.value = True
    assert editor.messages[-1][0] == "error" and "leaves" in editor.messages[-1][1]
    files.open_choice.value = "example.flowmc.json"
    files.open_button.value = True
    assert editor.state.path == tmp_path / "example.flowmc.json"
    assert files.upload("bad.flowmc.json", b"{ nope") and editor.messages[-1][0] == "error"
    text = flowmc.dumps(flowmc.load(tmp_path / "example.flowmc.json")).replace('"dx": 5.0', '"dx": 7.0')
    assert files.upload("up.flowmc.json", text.encode())
    assert editor.state.path is None and editor.state.node("shift").params["dx"] == 7.0
    assert "not saved" in unescape_md(editor.header.content)
    files.open(files.open_choice.value)  # unsaved upload: asks first
    modal, discard = editor.pending_modal
    discard.value = True
    assert editor.state.path is not None
    target = editor.export_gcode()
    assert target == tmp_path / "example.ngc" and "G1" in target.read_text()


def test_make_subgraph_open_it_and_come_back(editor, tmp_path):
    editor.state.select(nodes=["shift", "both"])
    editor.selection.sub_name.value = "inner"
    editor.selection.make_button.value = True
    new = editor.state.selected_nodes[0]
    assert editor.state.node(new).params == {"file": "inner.flowmc.json"}
    assert editor.state.issues() == []
    assert editor.selection.open_button.visible
    editor.selection.open_button.value = True
    assert editor.state.path == tmp_path / "inner.flowmc.json" and "opened from example" in unescape_md(editor.header.content)
    assert editor.selection.back_button.visible
    editor.state.set_param("shift", "dx", 9.0)
    editor.selection.back_button.value = True
    assert editor.state.path == tmp_path / "example.flowmc.json"
    assert flowmc.load(tmp_path / "inner.flowmc.json").node("shift").params["dx"] == 9.0
    assert run(editor).ok


def test_a_new_sub_graph_node_takes_a_free_spot_not_the_middle_of_what_it_replaced(editor):
    from flowmc.ui import arrange

    editor.state.select(nodes=["table", "both"])  # their middle is where 'shift' is
    editor.selection.sub_name.value = "ends"
    editor.selection.make_button.value = True
    new = editor.state.selected_nodes[0]
    rects = editor.actions.rects([b.node_id for b in editor.canvas.boxes])
    assert new in rects and arrange.overlaps(rects) == []
    assert editor.state.undo() and {n.id for n in editor.state.graph.nodes} >= {"table", "both"}  # one undo step


def test_drag_moves_nodes_and_records_one_undo_step(editor):
    import asyncio
    from types import SimpleNamespace

    index = [b.node_id for b in editor.canvas.boxes].index("shift")
    box = editor.canvas.boxes[index]
    start = (box.x + 0.5, box.y - 0.5, 0.0)

    def drag(phase, dx, dy):
        event = SimpleNamespace(phase=phase, instance_index=index, start_position=start,
                                end_position=(start[0] + dx, start[1] + dy, 0.0))
        asyncio.run(editor.canvas._on_drag(event))

    drag("start", 0, 0)
    drag("update", 0.5, 0.0)
    drag("end", 1.0, -1.0)
    assert editor.state.node("shift").pos == (320.0 + 1.0 / layout.SCALE, 0.0 + 1.0 / layout.SCALE)
    editor.edit_ops.value = "Undo"
    assert editor.state.node("shift").pos == (320.0, 0.0)


def test_view3d_front_panel_and_device_hooks(tmp_path):
    devices = DeviceSession()
    ed = Editor(example_file(tmp_path), port=0, devices=devices)
    try:
        ext = ed.extensions
        assert ext.failures == {}
        ext.device.connect_button.value = True  # the Device tab drives the editor's one device session
        assert devices.card is not None and ext.device.card is devices.card
        ed.run()
        assert ed.wait().ok
        deadline = time.time() + 10
        while time.time() < deadline and not ext.view.nodes:
            time.sleep(0.05)
        assert "/path/0" in ext.view.nodes  # the run's path went to the 3D view
    finally:
        ed.close()
    assert devices.card is None  # closing the editor closed its device session


def _serve(args, tmp_path):
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen([sys.executable, "-m", "flowmc", "serve", *args], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _url_line(proc, deadline=30.0):
    end = time.time() + deadline
    while time.time() < end:
        line = proc.stdout.readline()
        if line.startswith("flowmc editor: "):
            return line.split()[2]
    raise AssertionError("no URL printed")


def test_serve_prints_its_url_and_binds_localhost(tmp_path):
    path = example_file(tmp_path)
    proc = _serve([str(path), "--port", "0"], tmp_path)
    try:
        url = _url_line(proc)
        assert url.startswith("http://127.0.0.1:") and "/?token=" in url
        assert urllib.request.urlopen(url, timeout=10).status == 200
        with pytest.raises(urllib.error.HTTPError) as refused:  # without this launch's token: refused
            urllib.request.urlopen(url.split("?")[0], timeout=10)
        assert refused.value.code == 403
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    assert "network" not in err


def test_serve_on_another_host_warns(tmp_path):
    proc = _serve(["--host", "0.0.0.0", "--port", "0"], tmp_path)
    try:
        _url_line(proc)
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    assert "anyone" in err and "run the machine" in err


def test_serve_refuses_a_broken_file_without_a_traceback(tmp_path):
    (tmp_path / "bad.flowmc.json").write_text("{ nope")
    proc = subprocess.run([sys.executable, "-m", "flowmc", "serve", "bad.flowmc.json", "--port", "0"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "bad.flowmc.json" in proc.stderr and "Traceback" not in proc.stderr
    assert Path(tmp_path / "bad.flowmc.json").read_text() == "{ nope"


def test_failed_node_shows_its_error_on_the_canvas_and_in_the_list(tmp_path):
    g = flowmc.GraphBuilder(title="fails")
    n = g.add("basic.number", id="n", value=3.0, pos=(0, 0))
    d = g.add("basic.divide", id="d", b=0.0, pos=(300, 0))
    c = g.add("basic.check", id="c", min=0.0, pos=(600, 0))
    g.wire(n.value, d.a)
    g.wire(d.result, c.value)
    g.save(tmp_path / "fails.flowmc.json")
    ed = Editor(tmp_path / "fails.flowmc.json", port=0, extensions=False)
    try:
        result = run(ed)
        assert not result.ok
        assert {k: v[0] for k, v in ed.canvas.status.items()} == {"n": "done", "d": "failed", "c": "skipped"}
        labels = {k: v[0] for k, v in ed.canvas.texts.wanted.items()}
        assert labels["d/status"] == "failed: see Problems"  # the error's text is in the list, not over the canvas
        assert labels["n/status"].startswith("done · ") and labels["n/status"].endswith(" ms")
        assert labels["c/status"] == "skipped"
        assert "1 node failed" in unescape_md(ed.problems.summary.content)
        assert "division by zero" in ed.problems.buttons[0].label
        assert ed.messages[-1][0] == "error" and "division by zero" in ed.messages[-1][1]
        colours = ed.canvas._handles["body"].batched_colors
        from flowmc.ui import canvas_draw

        assert tuple(colours[1]) == tuple(canvas_draw.mesh_rgb(canvas_draw.STATUS_COLORS["failed"]))
    finally:
        ed.close()


def test_box_select_adds_the_nodes_inside(editor):
    boxes = {b.node_id: b for b in editor.canvas.boxes}
    a, b = boxes["table"], boxes["shift"]
    inside = editor.canvas.select_box(a.x - 0.1, b.y - b.h - 0.1, b.x + b.w + 0.1, a.y + 0.1)
    assert sorted(inside) == ["shift", "table"] and sorted(editor.state.selected_nodes) == ["shift", "table"]


def test_a_page_opening_120_nodes_gets_each_title_once_and_no_hidden_labels(tmp_path, open_editor):
    """At Fit a 120-node graph is too small to read port names: the page is sent the titles, one label each
    under one frame, and no detail labels made and dropped before it connected."""
    ed = open_editor(chain_file(tmp_path, 120), extensions=False)
    messages = messages_on_connect(ed)
    labels = [m["name"] for m in messages if m["type"] == "LabelMessage"]
    assert sorted(labels) == sorted(f"/canvas/titles/{b.node_id}.title" for b in ed.canvas.boxes)
    assert not [m for m in messages if m["type"] == "RemoveSceneNodeMessage"]
    frames = {m["name"] for m in messages if m["type"] == "FrameMessage"}
    assert not [f for f in frames if f.startswith(("/canvas/titles/", "/canvas/detail/"))]
    ed.canvas.texts.zoom(1.0)  # close enough to read: the details come, still one label per text
    ed.server.flush()
    again = messages_on_connect(ed)
    names = {m["name"] for m in again if m["type"] == "LabelMessage"}
    assert "/canvas/detail/t12.in.dx" in names and "/canvas/titles/t12.title" in names
    assert not [m for m in again if m["type"] == "FrameMessage" and m["name"].startswith("/canvas/detail/")]


def test_a_graph_opened_in_the_editor_is_framed_before_its_port_names_are_made(tmp_path, open_editor):
    """Opening a 120-node graph from a page showing a small one (port names shown): the editor fits the new
    graph before drawing it, so the page gets its titles and none of the 576 port-name labels it cannot read."""
    chain_file(tmp_path, 120)
    ed = open_editor(example_file(tmp_path), folder=tmp_path, extensions=False)
    seen_detail = []
    messages = messages_on_connect(ed, then=lambda: (seen_detail.append(ed.canvas.texts.detail),
                                                      ed.files.open("big.flowmc.json")))
    assert seen_detail == [True]  # the small graph's port names were shown
    labels = [m["name"] for m in messages if m["type"] == "LabelMessage"]
    assert sorted(labels) == sorted(f"/canvas/titles/{b.node_id}.title" for b in ed.canvas.boxes)
    assert len(ed.canvas.boxes) == 120 and not ed.canvas.texts.detail


def test_a_click_being_handled_when_the_editor_closes_ends_before_the_server_stops(tmp_path):
    """A test's teardown or Ctrl+C while a click's handler is still at work (here held at its start): close waits
    for it and its rebuild reaches the page's connection while it is open; viser would warn of every message
    queued on a closed connection (it did in the browser tests, a different one each run)."""
    editor = Editor(example_file(tmp_path), port=0, extensions=False)
    inside, go, ended = threading.Event(), threading.Event(), threading.Event()
    edit = editor.edit

    def held_edit(action):
        inside.set()
        go.wait(10)
        try:
            edit(action)
        finally:
            ended.set()

    editor.edit = held_edit
    closing = threading.Thread(target=editor.close)
    try:
        with warnings.catch_warnings(record=True) as seen, page(editor) as ws:
            warnings.simplefilter("always")
            end = time.monotonic() + 10
            while not editor.server.get_clients() and time.monotonic() < end:
                time.sleep(0.02)
            send_value(ws, editor.note_ops, "Comment")  # the Add: Comment button
            assert inside.wait(10)
            closing.start()
            closing.join(timeout=1.0)
            assert closing.is_alive()  # waiting for the click
            go.set()
            assert ended.wait(10)
            closing.join(timeout=15)
            assert not closing.is_alive()
    finally:
        go.set()
        if closing.ident is None:
            editor.close()
    assert editor.state.selected_notes  # the click did its work: a comment, selected
    assert not [w for w in seen if "closed connection" in str(w.message)], [str(w.message) for w in seen]


def test_closing_the_editor_stops_a_running_job_before_it_waits_for_a_click(tmp_path):
    """Ctrl+C on `flowmc serve` while the machine moves and a click is still being handled: the job stops at once,
    not once the click's handler ends (close waits up to 10 s for it)."""
    graph = tmp_path / "thesis_3axis.flowmc.json"
    graph.write_text((Path(flowmc.__file__).resolve().parents[1] / "graphs" / "thesis_3axis.flowmc.json").read_text())
    editor = Editor(graph, port=0, extensions=False)
    panel = editor.job_panel
    inside, go = threading.Event(), threading.Event()
    edit = editor.edit

    def held_edit(action):
        inside.set()
        go.wait(20)
        edit(action)

    editor.edit = held_edit
    closing = threading.Thread(target=editor.close)
    try:
        assert panel.start()
        end = time.monotonic() + 60
        while (panel.runner is None or panel.runner.state != "running") and time.monotonic() < end:
            time.sleep(0.05)
        runner = panel.runner
        assert runner is not None and runner.state == "running"
        with page(editor) as ws:
            end = time.monotonic() + 10
            while not editor.server.get_clients() and time.monotonic() < end:
                time.sleep(0.02)
            send_value(ws, editor.note_ops, "Comment")
            assert inside.wait(10)
            closing.start()
            end = time.monotonic() + 5
            while not runner.finished and time.monotonic() < end:
                time.sleep(0.02)
            assert closing.is_alive()  # still waiting for the click
            assert runner.finished, runner.state  # ... and the machine has stopped already
            go.set()
            closing.join(timeout=20)
    finally:
        go.set()
        if closing.ident is None:
            editor.close()
        closing.join(timeout=20)
