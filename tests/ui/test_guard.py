"""Only the editor's own page, holding this launch's token, may use the editor's server (issue 18 items 2
and 7): foreign origins, other host names (DNS rebinding) and missing or wrong tokens are refused on HTTP
and on the websocket, from Python clients and from a real browser page on another origin; a client
that is let in can change only the values of enabled, visible controls."""

from __future__ import annotations

import http.server
import socket
import threading
import time
import urllib.error
import urllib.request
from types import SimpleNamespace

import msgspec
import pytest
import viser
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from browser_helpers import chromium, wait_until
from editor_graphs import example_file
from flowmc.ui.guard import Guard
from flowmc.ui.viser_internals import update_allowed

PROTOCOL = f"viser-v{viser.__version__}"


@pytest.fixture
def editor(tmp_path, open_editor):
    return open_editor(example_file(tmp_path), extensions=False)


def _port(editor):
    return editor.server.get_port()


def _get(url, headers=None):
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, dict(response.headers), response.read()
    except urllib.error.HTTPError as err:
        return err.code, dict(err.headers), err.read()


def _ws(editor, *, origin="same", cookie=True, host=None, token=None):
    port = _port(editor)
    headers = {}
    if origin == "same":
        headers["Origin"] = f"http://127.0.0.1:{port}"
    elif origin is not None:
        headers["Origin"] = origin
    if cookie:
        headers["Cookie"] = f"{Guard.cookie_name(port)}={token or editor.guard.token}"
    if host is not None:
        headers["Host"] = host
    return connect(f"ws://127.0.0.1:{port}/", subprotocols=[PROTOCOL], additional_headers=headers, open_timeout=10)


# ---------------------------------------------------------------------------------------- the policy
def test_guard_policy_on_host_origin_and_token():
    guard = Guard("127.0.0.1", token="secret")
    ok = {"Host": "127.0.0.1:8080", "Origin": "http://127.0.0.1:8080", "Cookie": "flowmc-token-8080=secret"}
    assert guard.check(ok, "/", 8080).ok
    assert guard.check({**ok, "Host": "localhost:8080", "Origin": "http://localhost:8080"}, "/", 8080).ok
    assert guard.check({"Host": "127.0.0.1:8080"}, "/?token=secret", 8080).set_cookie
    refused = {
        "foreign origin": {**ok, "Origin": "http://evil.example"},
        "other local port": {**ok, "Origin": "http://127.0.0.1:9999"},
        "null origin": {**ok, "Origin": "null"},
        "rebinding host": {**ok, "Host": "evil.example:8080", "Origin": "http://evil.example:8080"},
        "other port in host": {**ok, "Host": "127.0.0.1:9999", "Origin": "http://127.0.0.1:9999"},
        "no host": {k: v for k, v in ok.items() if k != "Host"},
        "no token": {k: v for k, v in ok.items() if k != "Cookie"},
        "wrong token": {**ok, "Cookie": "flowmc-token-8080=guess"},
        "token of another port": {**ok, "Cookie": "flowmc-token-8081=secret"},
        "junk cookie": {**ok, "Cookie": "\x00;;=="},
    }
    for what, headers in refused.items():
        verdict = guard.check(headers, "/", 8080)
        assert not verdict.ok and verdict.status == 403, what
    assert not guard.check({"Host": "127.0.0.1:8080"}, "/?token=secre", 8080).ok
    assert Guard().token != Guard().token and len(Guard().token) >= 32


def test_other_hosts_only_with_an_explicit_bind():
    assert not Guard("127.0.0.1", token="t").check({"Host": "myhost:80"}, "/?token=t", 80).ok
    assert Guard("myhost", token="t").check({"Host": "myhost:80"}, "/?token=t", 80).ok
    assert Guard("127.0.0.1", token="t", hosts=["myhost"]).check({"Host": "myhost"}, "/?token=t", 80).ok


# ---------------------------------------------------------------------------------------- HTTP
def test_the_page_needs_the_token_and_sets_a_strict_cookie(editor):
    port = _port(editor)
    status, headers, body = _get(f"http://127.0.0.1:{port}/")
    assert status == 403 and b"token" in body and b"<html" not in body.lower()
    assert _get(f"http://127.0.0.1:{port}/?token=wrong")[0] == 403
    assert _get(editor.url, {"Host": f"evil.example:{port}"})[0] == 403
    status, headers, body = _get(editor.url)
    assert status == 200 and b"<html" in body.lower()
    cookie = headers["Set-Cookie"]
    assert cookie.startswith(f"flowmc-token-{port}={editor.guard.token};") and "HttpOnly" in cookie
    assert "SameSite=Strict" in cookie and headers["Referrer-Policy"] == "no-referrer"
    status, _, _ = _get(f"http://127.0.0.1:{port}/", {"Cookie": f"flowmc-token-{port}={editor.guard.token}"})
    assert status == 200


# ---------------------------------------------------------------------------------------- websocket
def test_websocket_refuses_foreign_origins_rebinding_and_missing_tokens(editor):
    with _ws(editor) as ws:  # the editor's own page: let in, and sent the GUI
        assert ws.recv(timeout=10)
    for kwargs in ({"origin": "http://evil.example"}, {"origin": f"http://localhost:{_port(editor) + 1}"},
                   {"cookie": False}, {"token": "wrong"},
                   {"host": "evil.example", "origin": "http://evil.example"}):
        with pytest.raises(InvalidStatus) as err:
            _ws(editor, **kwargs).close()
        assert err.value.response.status_code == 403, kwargs
    port = _port(editor)
    for host in ("evil.example", f"evil.example:{port}", f"127.0.0.1:{port + 1}"):  # a DNS-rebinding page's handshake
        raw = socket.create_connection(("127.0.0.1", port), timeout=10)
        raw.sendall((f"GET / HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                     f"Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                     f"Sec-WebSocket-Protocol: {PROTOCOL}\r\nOrigin: http://{host}\r\n"
                     f"Cookie: {Guard.cookie_name(port)}={editor.guard.token}\r\n\r\n").encode())
        assert raw.recv(100).startswith(b"HTTP/1.1 403"), host
        raw.close()


def _evil_site(html: str):
    """A page on another origin (another port of this machine) serving ``html``."""

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            body = html.encode()
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


@pytest.mark.browser
def test_a_page_from_another_origin_in_the_same_browser_cannot_connect(editor, monkeypatch):
    """The attack of the issue: the user has the editor open (its cookie is in the browser), then visits
    a page on another origin that opens the editor's websocket. 127.0.0.1 on another port is the same
    *site*, so the strict cookie is sent: only the Origin check stops it.

    Every step waits on a condition (the page's state, the guard's verdicts), never on a fixed sleep,
    so a loaded machine only makes it slower."""
    port = _port(editor)
    verdicts: list[tuple[str | None, bool]] = []  # (Origin, allowed) of every request the server saw
    check = editor.guard.check

    def recording(headers, path, at_port):
        verdict = check(headers, path, at_port)
        verdicts.append((headers.get("Origin"), verdict.ok))
        return verdict

    monkeypatch.setattr(editor.guard, "check", recording)
    probe = f"""<script>
      window.result = "pending";
      const ws = new WebSocket("ws://127.0.0.1:{port}/", ["{PROTOCOL}"]);
      ws.onopen = () => {{ window.result = "open"; }};
      ws.onerror = () => {{ window.result = "refused"; }};
    </script>"""
    evil = _evil_site(probe)
    try:
        with chromium() as browser:
            context = browser.new_context()  # one profile: the editor's cookie is there for every page
            page = context.new_page()
            page.goto(editor.url, timeout=120_000)  # the editor's own page: sets the cookie, and connects
            page.wait_for_function("window.__viserMutable?.nodeRefFromName?.['/canvas/body'] != null",
                                   timeout=120_000)
            wait_until(lambda: len(editor.server.get_clients()) == 1, timeout=120,
                       what="the editor's own page to connect")
            for evil_host in ("127.0.0.1", "localhost"):
                origin = f"http://{evil_host}:{evil.server_address[1]}"
                other = context.new_page()
                other.goto(f"{origin}/", timeout=120_000)
                other.wait_for_function("window.result !== 'pending'", timeout=120_000)
                assert other.evaluate("window.result") == "refused", evil_host
                wait_until(lambda o=origin: (o, False) in verdicts, timeout=120,
                           what=f"the server to refuse {origin}")  # refused by the guard, not lost on the way
                other.close()
            assert not any(ok for o, ok in verdicts if o is not None and str(evil.server_address[1]) in o)
            wait_until(lambda: len(editor.server.get_clients()) == 1, timeout=120,
                       what="only the editor's own page connected")
    finally:
        evil.shutdown()


# ---------------------------------------------------------------------------------------- client messages
def _send_update(ws, uuid, updates):
    ws.send(msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": uuid, "updates": updates}))


def _settle(ws, seconds=0.4):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            ws.recv(timeout=0.05)
        except TimeoutError:
            pass


def test_a_client_cannot_change_callbacks_or_disabled_controls(editor):
    download = editor.files.download_button
    callbacks = list(download._impl.update_cb)
    assert callbacks
    name_field = editor.files.save_as_name
    sync = name_field._impl.sync_cb
    assert sync is not None
    choice = editor.files.open_choice
    with _ws(editor) as ws:
        _send_update(ws, download._impl.uuid, {"update_cb": []})  # the attack
        _send_update(ws, name_field._impl.uuid, {"value": "x.flowmc.json", "sync_cb": None})
        _send_update(ws, choice._impl.uuid, {"value": "../../etc/passwd"})  # not one of its options
        _send_update(ws, name_field._impl.uuid, {"value": ["not", "text"]})
        editor.run_button.disabled = True
        _send_update(ws, editor.run_button._impl.uuid, {"value": True})  # a disabled button
        _send_update(ws, name_field._impl.uuid, {"value": "renamed.flowmc.json"})  # allowed: proves delivery
        _settle(ws)
    assert download._impl.update_cb == callbacks and name_field._impl.sync_cb is sync
    assert choice.value in choice.options and name_field.value == "renamed.flowmc.json"
    assert not editor.session.running and editor.last_result is None


def test_update_rules_for_each_kind_of_control(editor):
    gui = editor.server.gui
    number = gui.add_number("n", 1.0, min=0.0, max=10.0)
    slider = gui.add_slider("s", min=0, max=5, step=1, initial_value=2)
    vector = gui.add_vector3("v", (0.0, 0.0, 0.0))
    check = gui.add_checkbox("c", False)
    group = gui.add_button_group("g", ("A", "B"))
    hidden = gui.add_text("h", "", visible=False)

    def ok(handle, value):
        return update_allowed(gui, SimpleNamespace(uuid=handle._impl.uuid, updates={"value": value}))

    assert ok(number, 5) and not ok(number, 11) and not ok(number, float("nan")) and not ok(number, "5")
    assert ok(slider, 3) and not ok(slider, -1) and not ok(slider, True)
    assert ok(vector, [1, 2, 3]) and not ok(vector, [1, 2]) and not ok(vector, [1, 2, "x"])
    assert ok(check, True) and not ok(check, 1)
    assert ok(group, "B") and not ok(group, "C") and not ok(group, True)
    assert not ok(hidden, "x")
    assert update_allowed(gui, SimpleNamespace(uuid="no such control", updates={"anything": 1}))
