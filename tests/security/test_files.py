"""Issue 18 items 8 and 9: writes are atomic and explicit (no graph file, no file the graph reads, no
symbolic link is replaced; the editor asks before replacing), no temp file outlives a kill -9, long
names work, and nodes that read files see every change of content."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import flowmc
from editor_graphs import example_file
from flowmc.errors import FlowmcError, GraphError
from flowmc.fileio import TEMP_PATTERN, fingerprint, read_text, write_atomic
from flowmc.ui.app import Editor


def _gcode_out_graph(folder: Path, target: str) -> flowmc.Graph:
    (folder / "p.ngc").write_text("G21 G90\nG1 X10 F600\n")
    g = flowmc.GraphBuilder()
    src = g.add("path.gcode_in", id="gc", file="p.ngc")
    out = g.add("path.gcode_out", id="o", file=target)
    g.wire(src.path, out.path)
    graph = g.build()
    graph.path = folder / "g.flowmc.json"
    flowmc.save(graph, graph.path)
    return graph


@pytest.mark.parametrize("target, message", [
    ("other.flowmc.json", "graph file"),
    ("g.flowmc.json", "graph file"),
    ("p.ngc", "this graph reads"),
    ("link.ngc", "symbolic link"),
    ("sub", "folder"),
])
def test_writing_nodes_replace_no_graph_file_no_input_no_link(tmp_path, target, message):
    (tmp_path / "other.flowmc.json").write_text("{}")
    (tmp_path / "victim.txt").write_text("keep")
    (tmp_path / "sub").mkdir()
    os.symlink("victim.txt", tmp_path / "link.ngc")
    graph = _gcode_out_graph(tmp_path, target)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    result = flowmc.run(graph)
    assert not result.ok and message in result.errors[0] and result.errors[0].startswith("node 'o'")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before


def test_a_250_character_name_is_written_and_nothing_else_is_left(tmp_path):
    name = "a" * 246 + ".ngc"
    graph = _gcode_out_graph(tmp_path, name)
    assert flowmc.run(graph).ok
    assert "G1" in (tmp_path / name).read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([name, "g.flowmc.json", "p.ngc"])


def test_atomic_write_refuses_folders_links_and_pipes(tmp_path):
    (tmp_path / "d").mkdir()
    (tmp_path / "real").write_text("old")
    os.symlink("real", tmp_path / "link")
    os.mkfifo(tmp_path / "pipe")
    for name, message in (("d", "folder"), ("link", "symbolic link"), ("pipe", "pipe")):
        with pytest.raises(FlowmcError, match=message):
            write_atomic(tmp_path / name, "new")
    assert (tmp_path / "real").read_text() == "old"
    with pytest.raises(GraphError, match="folder"):
        flowmc.save(flowmc.Graph(), tmp_path / "d")
    with pytest.raises(FlowmcError, match="pipe or device"):
        read_text(tmp_path / "pipe")
    (tmp_path / "bom.txt").write_bytes(b"\xef\xbb\xbfG1 X1")
    assert read_text(tmp_path / "bom.txt") == "G1 X1"


WRITER = """
import sys
from flowmc.fileio import write_atomic
target, size = sys.argv[1], int(sys.argv[2])
print("ready", flush=True)
i = 0
while True:
    write_atomic(target, (b"AB"[i % 2:i % 2 + 1]) * size)
    i += 1
"""


def test_kill_9_while_writing_leaves_the_old_or_the_new_file_whole_and_no_temp_file(tmp_path):
    target = tmp_path / "part.ngc"
    target.write_bytes(b"A" * 4_000_000)
    for k in range(12):
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(target), "4000000"], stdout=subprocess.PIPE)
        assert proc.stdout.readline().strip() == b"ready"
        time.sleep(0.05 + 0.037 * k)  # different points inside the write loop
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        proc.stdout.close()
        data = target.read_bytes()
        assert len(data) == 4_000_000 and data in (b"A" * 4_000_000, b"B" * 4_000_000)
    leftovers = [p.name for p in tmp_path.iterdir() if p.name != "part.ngc"]
    assert all(TEMP_PATTERN.match(n) for n in leftovers), leftovers  # at most the instant-named ones
    write_atomic(target, "done")  # the next write in the folder removes what a dead writer left
    assert [p.name for p in tmp_path.iterdir()] == ["part.ngc"]


def _same_size_and_time(path: Path, text: str) -> None:
    before = path.stat()
    assert len(text.encode()) == before.st_size
    path.write_text(text)
    os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns))
    assert path.stat().st_size == before.st_size and path.stat().st_mtime_ns == before.st_mtime_ns


def test_file_reading_nodes_see_a_rewrite_with_the_same_size_and_time(tmp_path):
    program = tmp_path / "part.ngc"
    program.write_text("G21 G90\nG1 X10 F600\n")
    (tmp_path / "subs").mkdir()
    (tmp_path / "subs" / "s.ngc").write_text("o<s> sub\nG1 Y1\no<s> endsub\n")
    g = flowmc.GraphBuilder()
    src = g.add("path.gcode_in", id="gc", file="part.ngc", subroutine_folder="subs")
    g.output("path", "Path", src.path)
    graph = g.build()
    graph.path = tmp_path / "g.flowmc.json"
    runtime = flowmc.Runtime()
    assert runtime.run(graph).executed == ["gc"]
    assert runtime.run(graph).cached == ["gc"]  # unchanged: read once (a sweep parses once per worker)
    _same_size_and_time(program, "G21 G90\nG1 X20 F600\n")
    again = runtime.run(graph)
    assert again.executed == ["gc"] and again.outputs["path"].end.tolist() == [20.0, 0.0, 0.0]
    assert runtime.run(graph).cached == ["gc"]
    _same_size_and_time(tmp_path / "subs" / "s.ngc", "o<s> sub\nG1 Y2\no<s> endsub\n")  # a file in a folder it reads
    assert runtime.run(graph).executed == ["gc"]
    assert fingerprint(tmp_path / "subs") is None and fingerprint(tmp_path / "nope") is None


@pytest.fixture
def editor(tmp_path):
    ed = Editor(example_file(tmp_path), port=0, extensions=False)
    yield ed
    ed.close()


def test_editor_export_asks_before_replacing_and_never_replaces_what_the_graph_reads(editor, tmp_path):
    target = editor.export_gcode()
    assert target == tmp_path / "example.ngc" and "G1" in target.read_text()
    target.write_text("mine")
    editor.pending_modal = None
    assert editor.export_gcode() is None and target.read_text() == "mine"  # asks first
    modal, replace = editor.pending_modal
    replace.value = True
    assert "G1" in target.read_text() and editor.messages[-1] == ("info", "wrote example.ngc")

    (tmp_path / "part.ngc").write_text("G21 G90\nG1 X10 F600\n")
    g = flowmc.GraphBuilder()
    g.output("path", "Path", g.add("path.gcode_in", id="gc", file="part.ngc").path)
    g.save(tmp_path / "part.flowmc.json")
    editor.files.open("part.flowmc.json", confirmed=True)
    editor.pending_modal = None
    assert editor.export_gcode() is None and editor.pending_modal is None
    assert editor.messages[-1][0] == "error" and "this graph reads" in editor.messages[-1][1]
    assert (tmp_path / "part.ngc").read_text() == "G21 G90\nG1 X10 F600\n"


def test_editor_save_as_asks_before_replacing_refuses_folders_and_takes_a_bom(editor, tmp_path):
    files = editor.files
    (tmp_path / "other.flowmc.json").write_text("keep")
    editor.pending_modal = None
    assert not files.save_as("other") and (tmp_path / "other.flowmc.json").read_text() == "keep"
    modal, replace = editor.pending_modal
    replace.value = True
    assert flowmc.load(tmp_path / "other.flowmc.json").node("table") is not None
    (tmp_path / "dir.flowmc.json").mkdir()
    assert not files.save_as("dir")
    assert editor.messages[-1][0] == "error" and "folder" in editor.messages[-1][1]
    text = flowmc.dumps(flowmc.load(tmp_path / "example.flowmc.json"))
    assert files.upload("bom.flowmc.json", b"\xef\xbb\xbf" + text.encode())
    assert editor.messages[-1][0] == "info" and editor.state.node("table") is not None


def test_a_surrogate_upload_is_refused_and_save_still_works(editor, tmp_path):
    files = editor.files
    bad = flowmc.dumps(flowmc.load(tmp_path / "example.flowmc.json")).replace('"title": "example"', '"title": "\\ud800"')
    assert "\\ud800" in bad
    assert files.upload("bad.flowmc.json", bad.encode())
    assert editor.messages[-1][0] == "error" and "surrogate" in editor.messages[-1][1]
    assert files.save() and editor.messages[-1] == ("info", "saved example.flowmc.json")


def test_a_second_tab_is_told_that_tabs_share_one_graph_and_undo(editor):
    import msgspec
    import viser
    import zstandard
    from websockets.sync.client import connect

    from flowmc.ui.guard import Guard

    port = editor.server.get_port()
    headers = {"Origin": f"http://127.0.0.1:{port}", "Cookie": f"{Guard.cookie_name(port)}={editor.guard.token}"}

    def tab():
        ws = connect(f"ws://127.0.0.1:{port}/", subprotocols=[f"viser-v{viser.__version__}"],
                     additional_headers=headers, open_timeout=30)
        camera = {"type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [0.0, 0.0, 5.0],
                  "fov": 1.0, "near": 0.01, "far": 100.0, "image_height": 600, "image_width": 800,
                  "look_at": [0.0, 0.0, 0.0], "up_direction": [0.0, 0.0, 1.0]}
        ws.send(msgspec.msgpack.encode(camera))  # a page counts as a client once it reports its camera
        return ws

    def heard(ws, text: bytes, seconds: float = 30.0) -> bool:
        """Whether a frame to this tab carries ``text`` (frames: sizes, then zstd-compressed msgpack)."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                frame = ws.recv(timeout=0.5)
            except TimeoutError:
                continue
            size = int.from_bytes(frame[8:16], "little")
            if text in zstandard.ZstdDecompressor().decompressobj().decompress(frame[16:16 + size]):
                return True
        return False

    with tab() as first:
        assert not heard(first, b"share one undo history", seconds=2.0)  # alone: nothing to say
        with tab() as second:
            assert heard(second, b"share one undo history") and heard(first, b"share one undo history")


def test_a_writing_node_may_write_into_the_subroutine_folder_it_reads(tmp_path):
    (tmp_path / "p.ngc").write_text("G21 G90\nG1 X10 F600\n")
    g = flowmc.GraphBuilder()
    src = g.add("path.gcode_in", id="gc", file="p.ngc", subroutine_folder=".")
    g.wire(src.path, g.add("path.gcode_out", id="o", file="out.ngc").path)
    graph = g.build()
    graph.path = tmp_path / "g.flowmc.json"
    assert flowmc.run(graph).ok and flowmc.run(graph).ok  # the second run replaces its own output
    assert "G1" in (tmp_path / "out.ngc").read_text() and "G1 X10" in (tmp_path / "p.ngc").read_text()
