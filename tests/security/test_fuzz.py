"""The fuzz test of issue 18: seeded mutations of graph files, G-code programs and websocket messages
give clean errors only (no traceback, no internal error, no Python exception name, no terminal
escape), each batch in a child process under an address-space cap. benchmarks/security.py --fuzz
runs 10,000 of each and measures peak memory."""

from __future__ import annotations

import random
import time

import msgspec
import pytest
import viser
from websockets.sync.client import connect

from editor_graphs import example_file
from flowmc.ui.app import Editor
from flowmc.ui.guard import Guard
from fuzzing import cases, run_child

COUNT = 120
SEED = 18


def test_the_mutations_are_seeded_and_varied():
    first = [c.text for c in cases("graph", 40, SEED)]
    assert first == [c.text for c in cases("graph", 40, SEED)]
    assert first != [c.text for c in cases("graph", 40, SEED + 1)]
    assert len(set(first)) > 35
    programs = [c.text for c in cases("gcode", 40, SEED)]
    assert len(set(programs)) > 35 and any("\x1b" in p or "\0" in p for p in programs)


@pytest.mark.parametrize("kind", ["graph", "gcode"])
def test_mutated_inputs_give_clean_errors_only(kind, tmp_path):
    outcome = run_child(kind, 0, COUNT, SEED, tmp_path / kind, timeout=900)
    assert outcome.exit == 0 and outcome.count == COUNT, outcome
    assert outcome.bad == [], outcome.bad[:5]


def _messages(rng: random.Random, uuids: list[str]) -> list[bytes]:
    """Mutated client messages: GUI updates to real controls with hostile fields and values, other message
    types with junk fields, broken msgpack, and plain bytes."""
    values = [None, True, 1e308, float("nan"), -1, "x" * 5000, "../../etc/passwd", [], {}, [1, 2, 3],
              {"update_cb": []}, "\ud800".encode("utf-8", "surrogatepass").decode("utf-8", "replace")]
    keys = ["value", "update_cb", "sync_cb", "disabled", "visible", "options", "min", "max", "label", "_impl",
            "__class__", "order", "hint", "color"]
    out = []
    for _ in range(300):
        kind = rng.randrange(6)
        if kind <= 2:
            updates = {rng.choice(keys): rng.choice(values) for _ in range(rng.randint(0, 3))}
            msg = {"type": "GuiUpdateMessage", "uuid": rng.choice(uuids + ["nope", ""]), "updates": updates}
            out.append(msgspec.msgpack.encode(msg))
        elif kind == 3:
            msg = {"type": rng.choice(["ViewerCameraMessage", "ScenePointerMessage", "SceneNodeClickMessage",
                                       "FileTransferStartUpload", "FileTransferPart", "TransformControlsUpdateMessage",
                                       "NoSuchMessage", ""]),
                   rng.choice(keys + ["source_uuid", "transfer_uuid", "size_bytes", "part"]): rng.choice(values)}
            out.append(msgspec.msgpack.encode(msg))
        elif kind == 4:
            good = msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": rng.choice(uuids), "updates": {"value": 1}})
            out.append(good[: rng.randrange(len(good))])
        else:
            out.append(bytes(rng.randrange(256) for _ in range(rng.randrange(1, 200))))
    return out


def test_mutated_websocket_messages_leave_the_editor_whole_for_every_client(tmp_path, capfd):
    editor = Editor(example_file(tmp_path), port=0, extensions=False)
    try:
        port = editor.server.get_port()
        headers = {"Origin": f"http://127.0.0.1:{port}", "Cookie": f"{Guard.cookie_name(port)}={editor.guard.token}"}
        protocol = [f"viser-v{viser.__version__}"]
        gui = editor.server.gui
        handles = dict(gui._gui_input_handle_from_uuid)
        callbacks = {uuid: list(h._impl.update_cb) for uuid, h in handles.items()}
        messages = _messages(random.Random(SEED), list(handles))
        for start in range(0, len(messages), 100):  # the server may drop a connection that sent junk: reconnect
            try:
                with connect(f"ws://127.0.0.1:{port}/", subprotocols=protocol, additional_headers=headers,
                             open_timeout=30) as ws:
                    for message in messages[start:start + 100]:
                        ws.send(message)
                    ws.recv(timeout=30)
            except Exception as exc:  # noqa: BLE001  a closed connection is a fine answer to junk
                assert "ConnectionClosed" in type(exc).__name__ or isinstance(exc, TimeoutError), exc
        with connect(f"ws://127.0.0.1:{port}/", subprotocols=protocol, additional_headers=headers,
                     open_timeout=30) as ws:  # a new client still gets the editor, and may still edit
            assert ws.recv(timeout=30)
            name = editor.files.save_as_name
            ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": name._impl.uuid,
                                            "updates": {"value": "after-fuzz"}}))
            deadline = time.monotonic() + 60
            while name.value != "after-fuzz" and time.monotonic() < deadline:
                time.sleep(0.02)
            assert name.value == "after-fuzz"
        assert {uuid: list(h._impl.update_cb) for uuid, h in handles.items()} == callbacks
        assert editor.files.open_choice.value in editor.files.open_choice.options
        deadline = time.monotonic() + 60
        while editor.session.running and time.monotonic() < deadline:  # junk pressed nothing that still runs
            time.sleep(0.05)
        editor.run_button.value = True
        result = editor.wait()
        assert result is not None and result.ok
    finally:
        editor.close()
    err = capfd.readouterr().err
    assert "Traceback" not in err, err[-3000:]
