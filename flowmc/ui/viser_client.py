"""viser 1.1.1's browser client, unpacked once by the server instead of in the page on every load.

viser ships its client as one self-extracting page (``viser/client/build/index.html``, 0.8 MB): on
every load the page decodes a base-88 text, inflates it with a zstd WebAssembly decoder and then hands
2.5 MB of script to the main thread as an inline module, which the browser must compile there before
anything else happens. Here the server unpacks it once per process (``files``) and serves the page as
an ordinary one (``page``): the stylesheet inline, the script as a file (``/flowmc-client/app.js``)
that the browser fetches and compiles while it parses the page, and the zstd decoder as a
``.wasm`` file (the client also decodes the server's messages with it, and finds it on
``globalThis.__viserZstdWasm``, where viser's own loader puts it).

The script and decoder are served for the browser to keep (``CACHE``, an ETag, a 304 to a matching
``If-None-Match``); the page is not (it carries the launch's token).

One start-up default is changed on the way: the client starts with viser's default lights and its
built-in HDRI environment map until the server's first messages say otherwise, and under software
WebGL loading and prefiltering that map (then recompiling every material without it) took seconds.
flowmc's scenes use neither (``guarded_server`` configures both off), so the served client starts
without them (``_PLAIN_START``).

And under software WebGL (SwiftShader, llvmpipe: what viser's own check calls software) the canvas is not
multisampled (``_SOFTWARE_START``): the 4x antialiased drawing buffer was most of the GPU process's work at
an open (reallocated at each canvas size, resolved at each frame). flowmc's wires are screen-space lines that
smooth their own edges, labels read the same and boxes are axis-aligned (their frames are kept a pixel wide,
``Canvas._frame_zoom``), so the canvas looks the same without it.
The page asks WebGL for its renderer once (``_PROBE``, the context then released) and viser's software
check reads that answer instead of making a throw-away context of its own.

A folded folder's contents are built when it is first unfolded, then kept (``_FOLDER_STATE``, ``_FOLDER_BODY``):
viser builds them at once, hidden, and the folded Machine section alone was about 550 of a page's elements.

The page opens the websocket as it starts, in viser's own socket worker (served as ``socket.js``), and reports the
client's first camera on it (``_EARLY_SOCKET``): viser's client would open it only after React mounted, and viser's
server runs its connect callbacks (the editor's framing and camera lock) only once a camera is reported, so the lock
came a frame after the first drawing. The client takes the page's worker and the messages it held (``_SOCKET_MAKE``).

viser's notice that WebGL runs in software closes itself after ``SOFTWARE_NOTICE_MS`` (``_SOFTWARE_NOTICE``): viser
keeps it until closed by hand, and it covered the side panel's palette for as long as the editor was open.

If the installed viser's page does not have the shape this expects, ``files()`` is None and viser
serves its own page, as before (slower, nothing else changes); tests/ui/test_viser_client.py fails then.
"""

from __future__ import annotations

import functools
import gzip
import hashlib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import viser
import zstandard

__all__ = ["ClientFiles", "files", "page", "asset", "PREFIX", "CACHE", "SOFTWARE_NOTICE_MS"]

PREFIX = "/flowmc-client/"
# The script and decoder never change under their address (it names their hash): a browser opening the editor
# again (a reload, a second tab) takes them from its cache, and Chromium then reuses the script's compiled code
# (V8's code cache) instead of compiling 2.5 MB again. The page itself is never cached (it holds the token).
CACHE = "private, max-age=31536000, immutable"
_INDEX = Path(viser.__file__).parent / "client" / "build" / "index.html"
_ALPHABET = "".join(chr(c) for c in range(0x21, 0x7F) if chr(c) not in "\"&<>'`")  # viser's base-88 digits
_PAYLOAD = re.compile(r'<script data-p="([^"]*)" data-ss="(\d+)" data-cs="(\d+)">(.*?)</script>', re.S)
_WASM = re.compile(r'gzWasm="((?:[^"\\]|\\.)*)"')
# The client's environment before the server configures one: default lights on, the built-in HDRI (null).
_DEFAULT_START = "enableDefaultLights:!0,enableDefaultLightsShadows:!0,environmentMap:null,"
_PLAIN_START = ("enableDefaultLights:!1,enableDefaultLightsShadows:!1,environmentMap:{type:`EnvironmentMapMessage`,"
                "hdri_data:null,background:!1,background_blurriness:0,background_intensity:1,"
                "background_wxyz:[1,0,0,0],environment_intensity:1,environment_wxyz:[1,0,0,0]},")

# viser's software-WebGL check (a throw-away context on every load) answers from the page's one probe, and
# react-three-fiber's renderer is multisampled only where that probe found a GPU.
_VISER_PROBE = ("function tfe(){let e=document.createElement(`canvas`),t=!1,n=`unknown`,r=`unknown`,i=!1,a=null;try{"
                "a=e.getContext(`webgl2`)||e.getContext(`webgl`)}catch{i=!0}if(a){t=!0;let e=a.getExtension("
                "`WEBGL_debug_renderer_info`);e?(n=a.getParameter(e.UNMASKED_RENDERER_WEBGL)??`unknown`,r=a.getParameter("
                "e.UNMASKED_VENDOR_WEBGL)??`unknown`):console.log(`WEBGL_debug_renderer_info unavailable; software "
                "rendering detection skipped.`)}else i||(t=!1);return{supported:t,renderer:n,vendor:r,"
                "contextCreationFailed:i}}")
_ANTIALIAS = "powerPreference:`high-performance`,antialias:!0,alpha:!0}"
# A folder's contents are built the first time it is unfolded (then kept): viser mounts a folded folder's
# contents hidden, and the folded Machine section alone is about 550 elements the page built at every open.
_FOLDER_STATE = "d=a.useGuiConfig(i??``,e=>i==null?null:e?.type??null);return n?t===null?"
_FOLDER_BODY = ("children:(0,Y.jsx)(Q,{pt:`0.2em`,children:(0,Y.jsx)(hz.Provider,{value:{...l,folderDepth:"
                "l.folderDepth+1},children:(0,Y.jsx)(l.GuiContainer,{containerUuid:e})})})")
# The websocket is opened by the page as it starts (``_EARLY_SOCKET``), in viser's own socket worker (its source,
# ``_WORKER``, served as a file): viser's client opens it from React once the page has mounted, and the server's
# first messages then wait for that. The client's effect takes the page's worker and the messages it has held, in
# order, instead of starting one (or starts its own, as before, if the page's is for another server).
_WORKER = re.compile(r"var f7='([^'\\]*)',p7=typeof self")
_SOCKET_MAKE = ("let a=new Wle,o=!1,s=null;function c(e){a.postMessage(e)}let l=m7();l!==void 0&&"
                "c({type:`zstd_wasm`,module:l});")
_SOCKET_START = "},c({type:`set_server`,server:n}),()=>{"
# viser's software-WebGL notice (kept until closed by hand) closes itself after this long: read, then out of the way.
SOFTWARE_NOTICE_MS = 8000
_SOFTWARE_NOTICE = ("Performance may be degraded. If this is unexpected, check that hardware acceleration is enabled "
                    "in your browser settings.`,autoClose:!1,color:`orange`}")
_SUBSTITUTIONS = ((_DEFAULT_START, _PLAIN_START),
                  (_SOFTWARE_NOTICE, _SOFTWARE_NOTICE.replace("autoClose:!1", f"autoClose:{SOFTWARE_NOTICE_MS}")),
                  (_VISER_PROBE, "function tfe(){return globalThis.__flowmcWebGL()}"),
                  (_ANTIALIAS, "powerPreference:`high-performance`,antialias:!globalThis.__flowmcWebGL().software,alpha:!0}"),
                  (_FOLDER_STATE, "d=a.useGuiConfig(i??``,e=>i==null?null:e?.type??null),f=b.useRef(!1);"
                                  "o&&!u&&(f.current=!0);return n?t===null?"),
                  (_FOLDER_BODY, "children:f.current?" + _FOLDER_BODY[len("children:"):] + ":null"),
                  (_SOCKET_MAKE, "let F=globalThis.__flowmcSocket;globalThis.__flowmcSocket=null;F?.server!==n&&"
                                 "(F?.worker.terminate(),F=null);let a=F?F.worker:new Wle,o=!1,s=null;function c(e){"
                                 "a.postMessage(e)}let l=m7();!F&&l!==void 0&&c({type:`zstd_wasm`,module:l});"),
                  (_SOCKET_START, "},F?F.held.splice(0).forEach(e=>a.onmessage(e)):c({type:`set_server`,server:n}),()=>{"))
# The page's probe, answered once: viser's fields (supported, renderer, vendor, contextCreationFailed) and
# ``software`` by viser's own test of the renderer's name.
_PROBE = """globalThis.__flowmcWebGL = () => globalThis.__flowmcGL ??= (() => {
  const out = {supported: false, renderer: "unknown", vendor: "unknown", contextCreationFailed: false, software: false};
  let gl = null;
  try { const canvas = document.createElement("canvas"); gl = canvas.getContext("webgl2") || canvas.getContext("webgl"); }
  catch { out.contextCreationFailed = true; }
  if (gl) {
    out.supported = true;
    const info = gl.getExtension("WEBGL_debug_renderer_info");
    if (info) {
      out.renderer = gl.getParameter(info.UNMASKED_RENDERER_WEBGL) ?? "unknown";
      out.vendor = gl.getParameter(info.UNMASKED_VENDOR_WEBGL) ?? "unknown";
    }
    out.software = /swiftshader|llvmpipe|softpipe|software/i.test(out.renderer);
    gl.getExtension("WEBGL_lose_context")?.loseContext();
  }
  return out;
})();"""

# The page's socket (``_WORKER`` above), for the server viser's client would pick (``?websocket=``, else the page's own
# address); its messages are held until the client takes them. A playback page (``?playbackPath=``) opens none.
# viser's server runs its connect callbacks (flowmc's page script, framing, camera lock) only once a page has reported
# its camera, which viser's client does once its scene has mounted: the page reports what the client's first report
# says (viser's default camera, a canvas the window's size), so that those messages come with the first ones too.
# It reports as the socket connects even where the client has taken the worker by then (its own handler replaced
# the page's; under load the client mounted first): a listener of its own, not the handler, sees the connection.
_EARLY_SOCKET = """const query = new URLSearchParams(location.search), named = query.getAll("websocket");
const socket = query.has("playbackPath") ? null : globalThis.__flowmcSocket = {
  worker: new Worker(SOCKET_URL, {type: "module"}), held: [],
  server: named.length ? named[0]
    : location.href.replace("http://", "ws://").replace("https://", "wss://").split("?")[0].replace(/\\/$/, "")};
if (socket) {
  socket.worker.onmessage = event => socket.held.push(event);
  socket.worker.addEventListener("message", function report(event) {
    if (event.data.type !== "connected") return;
    socket.worker.removeEventListener("message", report);
    socket.worker.postMessage({type: "send", message: {
      type: "ViewerCameraMessage", wxyz: [-0.1759199, 0.3398511, 0.8204732, -0.4247082], position: [3, 3, 3],
      image_height: Math.floor(innerHeight * devicePixelRatio), image_width: Math.floor(innerWidth * devicePixelRatio),
      fov: 75 * Math.PI / 180, near: 0.01, far: 1000, look_at: [0, 0, 0], up_direction: [0, 0, 1]}});
  });
  socket.worker.postMessage({type: "set_server", server: socket.server});
}"""


class Asset(NamedTuple):
    content_type: str
    body: bytes
    gzipped: bytes | None  # the body gzip-compressed, for browsers that accept it (None: not worth it)
    digest: str = ""  # the body's hash, in its address and its ETag ("" for the page, which is never cached)


@dataclass(frozen=True)
class ClientFiles:
    head: str  # viser's <head> up to its loader (charset, icon, title)
    css: str
    assets: dict[str, Asset]  # by name under PREFIX


def _base88(text: str) -> bytes:
    """viser's base-88 text (5 characters for 4 bytes, big-endian) back to bytes."""
    lut = np.zeros(128, np.int64)
    lut[[ord(c) for c in _ALPHABET]] = np.arange(88)
    whole, rest = divmod(len(text), 5)
    digits = lut[np.frombuffer(text[:whole * 5].encode("ascii"), np.uint8).reshape(whole, 5)]
    value = np.zeros(whole, np.int64)
    for k in range(5):
        value = value * 88 + digits[:, k]
    out = value.astype(">u4").tobytes()
    if rest:
        tail = 0
        for c in text[whole * 5:]:
            tail = tail * 88 + _ALPHABET.index(c)
        out += tail.to_bytes(rest - 1, "big")
    return out


def _asset(content_type: str, body: bytes) -> Asset:
    return Asset(content_type, body, gzip.compress(body, 1) if len(body) > 4096 else None,
                 hashlib.blake2b(body, digest_size=12).hexdigest())


@functools.cache
def files() -> ClientFiles | None:
    """The unpacked client (once per process), or None when viser's page is not the expected shape."""
    try:
        html = _INDEX.read_text("utf-8")
        found = _PAYLOAD.search(html)
        wasm_text = _WASM.search(found.group(4)) if found else None
        if found is None or wasm_text is None:
            return None
        styles, scripts = int(found.group(2)), int(found.group(3))
        raw = zstandard.ZstdDecompressor().decompress(_base88(found.group(1)), max_output_size=styles + scripts)
        script = raw[styles:].decode("utf-8")
        if len(raw) != styles + scripts or any(script.count(old) != 1 for old, _new in _SUBSTITUTIONS):
            return None
        workers = _WORKER.findall(script)
        if len(workers) != 1 or "new WebSocket(" not in workers[0]:
            return None
        for old, new in _SUBSTITUTIONS:
            script = script.replace(old, new)
        wasm = gzip.decompress(_base88(wasm_text.group(1).replace("\\\\", "\\")))
        if wasm[:4] != b"\0asm":
            return None
    except (OSError, ValueError, zstandard.ZstdError, gzip.BadGzipFile):
        return None
    head = html[:found.start()].rstrip()
    return ClientFiles(head, raw[:styles].decode("utf-8"),
                       {"app.js": _asset("text/javascript; charset=utf-8", script.encode("utf-8")),
                        "socket.js": _asset("text/javascript; charset=utf-8", workers[0].encode("utf-8")),
                        "zstd.wasm": _asset("application/wasm", wasm)})


def page(token: str) -> str | None:
    """The client's page: the script and decoder are fetched with ``token`` (a cross-site frame, like the
    3D view, sends no cookie) under addresses naming their content's hash, so a browser may keep them
    (``CACHE``). None when the client could not be unpacked."""
    client = files()
    if client is None:
        return None
    app, socket, wasm = (f"{PREFIX}{name}?v={client.assets[name].digest}&token={token}"
                         for name in ("app.js", "socket.js", "zstd.wasm"))
    early = _EARLY_SOCKET.replace("SOCKET_URL", f'"{socket}"')
    return (f'{client.head}\n<style>{client.css}</style>\n<link rel="modulepreload" href="{app}" />\n<script>{_PROBE}</script>\n'
            f'<script type="module">{early}\nglobalThis.__viserZstdWasm = await WebAssembly.compileStreaming(fetch("{wasm}"));\n'
            f'socket?.worker.postMessage({{type: "zstd_wasm", module: globalThis.__viserZstdWasm}});\n'
            f'await import("{app}");</script>\n</head>\n<body>\n<noscript>You need to enable JavaScript to run this app.'
            f'</noscript>\n<div id="root"></div>\n</body>\n</html>\n')


def asset(path: str) -> Asset | None:
    """The file served at ``path`` (under ``PREFIX``, query stripped), if it is one of the client's."""
    client = files()
    if client is None or not path.startswith(PREFIX):
        return None
    return client.assets.get(path[len(PREFIX):])
