"""The editor serves viser's client unpacked (flowmc.ui.viser_client): the page is an ordinary one that fetches
the script and the zstd decoder as files, behind the same guard as the page, and the client starts without
viser's default lights and HDRI environment (which flowmc's scenes never use). A real browser runs it."""

from __future__ import annotations

import gzip
import json
import time
import urllib.error
import urllib.request

import pytest

from browser_helpers import EditorPage, chromium
from editor_graphs import example_file
from flowmc.ui import viser_client
from flowmc.ui.viser_client import SOFTWARE_NOTICE_MS


def _joined(message):
    """Each header once, a repeated one's values joined (as a browser reads them)."""
    return {key: ", ".join(message.get_all(key)) for key in set(message.keys())}


def _get(url, headers=None):
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=20) as response:
            return response.status, _joined(response.headers), response.read()
    except urllib.error.HTTPError as err:
        return err.code, _joined(err.headers), err.read()


@pytest.fixture
def editor(tmp_path, open_editor):
    return open_editor(example_file(tmp_path), extensions=False)


def test_the_installed_viser_client_unpacks_and_starts_plain():
    client = viser_client.files()
    assert client is not None, "viser's index.html is not the shape viser_client expects: the editor serves it packed"
    script = client.assets["app.js"].body.decode()
    assert viser_client._PLAIN_START in script and viser_client._DEFAULT_START not in script
    assert viser_client._VISER_PROBE not in script and viser_client._ANTIALIAS not in script
    assert "antialias:!globalThis.__flowmcWebGL().software" in script
    assert viser_client._FOLDER_STATE not in script and viser_client._FOLDER_BODY not in script
    assert "createRoot" in script and len(script) > 1_000_000
    assert client.assets["zstd.wasm"].body[:4] == b"\0asm"
    assert viser_client._SOCKET_MAKE not in script and viser_client._SOCKET_START not in script
    assert "new WebSocket(" in client.assets["socket.js"].body.decode()
    assert gzip.decompress(client.assets["app.js"].gzipped) == client.assets["app.js"].body
    assert ".mantine-" in client.css and "<title>" in client.head


def test_the_page_and_its_files_are_served_behind_the_guard(editor):
    port, token = editor.server.get_port(), editor.guard.token
    status, headers, body = _get(editor.url)
    page = body.decode()
    assert headers["Cache-Control"] == "no-store"  # the page carries the token: never kept
    assert status == 200 and headers["Content-Type"].startswith("text/html")
    assert "data-p=" not in page and f'{viser_client.PREFIX}app.js?v=' in page and f"token={token}" in page
    base = f"http://127.0.0.1:{port}{viser_client.PREFIX}"
    status, headers, body = _get(f"{base}app.js?token={token}", {"Accept-Encoding": "gzip"})
    assert status == 200 and headers["Content-Encoding"] == "gzip" and headers["Cache-Control"] == viser_client.CACHE
    assert gzip.decompress(body) == viser_client.files().assets["app.js"].body
    digest = viser_client.files().assets["app.js"].digest
    assert f"app.js?v={digest}&" in page and headers["ETag"] == f'W/"{digest}"'
    status, headers, body = _get(f"{base}app.js?token={token}", {"If-None-Match": f'W/"{digest}"'})
    assert status == 304 and body == b"" and headers["Cache-Control"] == viser_client.CACHE
    status, headers, body = _get(f"{base}socket.js?token={token}")
    assert status == 200 and headers["Content-Type"].startswith("text/javascript") and b"new WebSocket(" in body
    assert f"socket.js?v={viser_client.files().assets['socket.js'].digest}&" in page
    assert _get(f"{base}socket.js")[0] == 403
    status, headers, body = _get(f"{base}zstd.wasm?token={token}")
    assert status == 200 and headers["Content-Type"] == "application/wasm" and body[:4] == b"\0asm"
    assert _get(f"{base}app.js")[0] == 403  # no token, no cookie
    assert _get(f"{base}app.js?token=wrong")[0] == 403
    assert _get(f"{base}other.js?token={token}")[0] == 404  # viser's own server: not a file of its client


@pytest.mark.browser
def test_a_browser_runs_the_served_client_without_the_default_environment(editor):
    with chromium() as browser:
        ui = EditorPage(browser, editor)
        errors: list[str] = []
        ui.page.on("pageerror", lambda e: errors.append(str(e)))
        ui.open(timeout=60)
        assert ui.page.evaluate("document.querySelector('script[data-p]') === null")
        assert ui.page.evaluate("globalThis.__viserZstdWasm instanceof WebAssembly.Module")
        # no environment map ever set on the scene, and no default directional lights
        assert ui.page.evaluate("window.__viserMutable.scene.environment === null")
        lights = ui.page.evaluate("""() => { let n = 0; window.__viserMutable.scene.traverse(o => {
            if (o.isDirectionalLight) n++; }); return n; }""")
        assert lights == 0
        assert errors == []
        ui.page.close()


@pytest.mark.browser
def test_software_webgl_is_probed_once_and_the_canvas_is_not_multisampled(editor):
    """Under SwiftShader the page's one probe says software: viser's notice still shows (its check reads the
    probe) and then closes itself, no other throw-away context is made, and the renderer's context has no
    antialiasing."""
    with chromium() as browser:
        page = browser.new_page()
        page.add_init_script("""(() => { const get = HTMLCanvasElement.prototype.getContext; window.__contexts = 0;
            HTMLCanvasElement.prototype.getContext = function (kind, ...rest) {
              if (String(kind).startsWith('webgl')) window.__contexts++; return get.call(this, kind, ...rest); }; })()""")
        page.goto(editor.url)
        page.wait_for_function("window.__flowmcCameraLocked === true", timeout=60000)
        notice = page.get_by_text("Software WebGL rendering detected")
        notice.wait_for(timeout=10000)
        shown = time.monotonic()
        probe = page.evaluate("globalThis.__flowmcGL")
        assert probe["software"] is True and probe["supported"] is True and "SwiftShader" in probe["renderer"]
        assert page.evaluate("window.__viserMutable.canvas.getContext('webgl2').getContextAttributes().antialias") is False
        assert page.evaluate("window.__contexts") == 3  # the probe, the renderer's, and the line above asking again
        notice.wait_for(state="hidden", timeout=SOFTWARE_NOTICE_MS + 10000)
        assert time.monotonic() - shown > SOFTWARE_NOTICE_MS / 1000 - 1.0  # it stayed to be read
        page.close()


@pytest.mark.browser
def test_a_folded_folder_is_built_when_first_unfolded_then_kept(editor):
    """The folded Machine section is not in the page at open (E-STOP, outside it, is); unfolded, it shows what the
    server holds now (a value changed while it was folded), and folding it again keeps the same elements."""
    with chromium() as browser:
        ui = EditorPage(browser, editor)
        ui.open(timeout=60)
        page = ui.page
        assert page.get_by_role("button", name="E-STOP").is_visible()
        assert page.get_by_text("Start options", exact=True).count() == 0
        assert page.get_by_role("button", name="Start", exact=True).count() == 0
        editor.job_panel.feed.value = 150
        page.get_by_text("Machine", exact=True).first.click()
        start = page.get_by_role("button", name="Start", exact=True)
        start.wait_for(state="visible", timeout=10000)
        assert start.is_enabled() and page.get_by_text("Start options", exact=True).count() == 1
        feed = ui.field("Feed %")
        assert feed.input_value() == "150"
        start.evaluate("e => { e.__kept = true; }")
        page.get_by_text("Machine", exact=True).first.click()
        start.wait_for(state="hidden", timeout=10000)
        page.get_by_text("Machine", exact=True).first.click()
        start.wait_for(state="visible", timeout=10000)
        assert start.evaluate("e => e.__kept === true")
        page.close()


_WORKERS = """(() => { const W = window.Worker; window.__workers = [];
    window.Worker = function (url, options) {
      window.__workers.push({url: String(url), clientStarted: !!document.getElementById('root')?.hasChildNodes()});
      return new W(url, options); }; window.Worker.prototype = W.prototype; })()"""


@pytest.mark.browser
def test_the_page_opens_the_websocket_before_the_client_starts_and_the_client_takes_it(editor):
    """The page starts viser's socket worker before the client's script has run; the client takes that worker and
    the messages it held (the page opens as before) instead of opening a second connection."""
    with chromium() as browser:
        ui = EditorPage(browser, editor)
        ui.page.add_init_script(_WORKERS)
        errors: list[str] = []
        ui.page.on("pageerror", lambda e: errors.append(str(e)))
        ui.open(timeout=60)
        workers = ui.page.evaluate("window.__workers")
        assert [w["url"].partition("?")[0] for w in workers] == [f"{viser_client.PREFIX}socket.js"]
        assert workers[0]["clientStarted"] is False
        assert ui.page.evaluate("globalThis.__flowmcSocket") is None  # taken by the client
        assert len(editor.server.get_clients()) == 1 and errors == []
        ui.page.close()


@pytest.mark.browser
def test_the_page_reports_the_camera_as_the_socket_connects_so_the_lock_does_not_wait_for_the_client(editor):
    """viser runs its connect callbacks (here the editor's camera lock) once a page reports its camera: the page reports
    the client's first camera itself while it handles the socket's connection, whether or not the client has taken the
    socket by then (under load it has: its scene mounted first), so the lock does not wait for the client's own report
    (made once its scene has mounted, 50 ms after the connection). Who sent a report is read from its call stack (the
    client's code is served under PREFIX; the page's is inline); when the lock comes back depends on the server's load."""
    with chromium() as browser:
        ui = EditorPage(browser, editor)
        ui.page.add_init_script("""(() => { window.__events = []; const post = Worker.prototype.postMessage;
            Worker.prototype.postMessage = function (m, ...rest) {
              if (m?.type === "send" && m.message.type === "ViewerCameraMessage") window.__events.push(
                new Error().stack.includes(%s) ? "client camera" : "page camera");
              return post.call(this, m, ...rest); };
            const W = window.Worker; window.Worker = function (...a) { const w = new W(...a);
              w.addEventListener("message", e => {
                if (e.data.type === "connected") {  // first of the event's listeners; the timer fires after the last
                  window.__events.push("connected"); setTimeout(() => window.__events.push("connection handled")); }
                if (e.data.type === "message_batch" && e.data.messages.some(
                  m => m.type === "RunJavascriptMessage" && m.source.includes("flowmcLockCamera"))) {
                  window.__events.push("lock"); } });
              return w; }; window.Worker.prototype = W.prototype; })()""" % json.dumps(viser_client.PREFIX))
        ui.open(timeout=60)
        events = ui.page.evaluate("window.__events")
        assert events.count("connected") == 1 and events.count("page camera") == 1, events
        connected, handled = events.index("connected"), events.index("connection handled")
        assert "page camera" in events[connected + 1:handled], events
        assert "lock" in events[handled:] and "client camera" in events[handled:], events
        ui.page.close()


@pytest.mark.browser
def test_an_early_socket_for_another_address_is_closed_and_the_client_opens_its_own(editor):
    """Where the page's socket is not for the server the client picks (here made so: its address is changed as the
    page stores it), the client closes it and connects itself, as viser's client does without the page's socket."""
    with chromium() as browser:
        ui = EditorPage(browser, editor)
        ui.page.add_init_script(_WORKERS)
        ui.page.add_init_script("""Object.defineProperty(globalThis, "__flowmcSocket", {configurable: true,
            get() { return this.__kept; }, set(v) { if (v) v.server = "ws://127.0.0.1:9/elsewhere"; this.__kept = v; }})""")
        ui.open(timeout=60)
        workers = ui.page.evaluate("window.__workers")
        assert len(workers) == 2 and workers[1]["url"].startswith("blob:") and workers[1]["clientStarted"] is True
        deadline = time.monotonic() + 10
        while len(editor.server.get_clients()) != 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert len(editor.server.get_clients()) == 1
        ui.page.close()


@pytest.mark.browser
def test_a_second_open_in_the_same_browser_takes_the_client_from_its_cache(editor, browser):
    context = browser.new_context()
    try:
        sources = []
        for _ in range(2):
            page = context.new_page()
            cdp = context.new_cdp_session(page)
            cdp.send("Network.enable")
            seen: dict[str, bool] = {}
            cdp.on("Network.responseReceived", lambda e, seen=seen: seen.update(
                {e["response"]["url"].partition("?")[0].rpartition("/")[2]: bool(e["response"].get("fromDiskCache"))}))
            page.goto(editor.url)
            page.wait_for_function("window.__flowmcCameraLocked === true", timeout=60000)
            sources.append(seen)
            page.close()
        assert sources[0]["app.js"] is False and sources[0]["zstd.wasm"] is False
        assert sources[1]["app.js"] is True and sources[1]["zstd.wasm"] is True  # the page itself is fetched again
        assert sources[1][""] is False
    finally:
        context.close()
