"""What a new page is sent, read with a browserless websocket client speaking viser 1.1.1's private wire
format (kept here, in one place): the client sends a camera message first (the server registers it only
then), and every server frame is 8 bytes raw length, 8 bytes compressed length, then zstd-compressed
msgpack ``{"messages": [...], ...}``."""

from __future__ import annotations

import contextlib
import struct
import time
from typing import Any, Callable, Iterator

import msgspec
import viser
import zstandard
from websockets.sync.client import connect

from flowmc.ui.guard import Guard

_CAMERA = {"type": "ViewerCameraMessage", "wxyz": [1.0, 0.0, 0.0, 0.0], "position": [0.0, 0.0, 10.0], "fov": 0.7,
           "near": 0.01, "far": 1000.0, "image_height": 1000, "image_width": 1200, "look_at": [0.0, 0.0, 0.0],
           "up_direction": [0.0, 1.0, 0.0]}


def _decode(frame: bytes) -> list[dict[str, Any]]:
    raw_len, packed_len = struct.unpack("<QQ", frame[:16])
    body = zstandard.ZstdDecompressor().decompress(frame[16:16 + packed_len], max_output_size=raw_len)
    return msgspec.msgpack.decode(body)["messages"]


def _drain(ws: Any, quiet_s: float, timeout_s: float) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            frame = ws.recv(timeout=quiet_s)
        except TimeoutError:
            break
        if isinstance(frame, bytes):
            out += _decode(frame)
    return out


@contextlib.contextmanager
def page(editor: Any) -> Iterator[Any]:
    """A page connected to ``editor`` (the websocket, its camera message sent)."""
    port = editor.server.get_port()
    headers = {"Origin": f"http://127.0.0.1:{port}", "Cookie": f"{Guard.cookie_name(port)}={editor.guard.token}"}
    with connect(f"ws://127.0.0.1:{port}/", subprotocols=[f"viser-v{viser.__version__}"], additional_headers=headers,
                 open_timeout=10, max_size=None) as ws:
        ws.send(msgspec.msgpack.encode(_CAMERA))
        yield ws


def send_value(ws: Any, handle: Any, value: Any) -> None:
    """What the page sends when a control is used (a button group clicked: the label)."""
    ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid, "updates": {"value": value}}))


def messages_on_connect(editor: Any, quiet_s: float = 1.0, timeout_s: float = 30.0,
                        then: Callable[[], object] | None = None) -> list[dict[str, Any]]:
    """Every message the editor sends a page that just connected, until it has been quiet for ``quiet_s``;
    with ``then``: the messages sent after that, while and after ``then()`` runs, instead."""
    with page(editor) as ws:
        out = _drain(ws, quiet_s, timeout_s)
        if then is not None:
            then()
            out = _drain(ws, quiet_s, timeout_s)
    return out
