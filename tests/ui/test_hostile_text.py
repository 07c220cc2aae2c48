"""Text from files never becomes markup (issue 18 items 1 and 3).

A hostile string goes everywhere a file can put text (graph title and description, a node type, params,
an interface description, a G-code line, a folder and file names, an uploaded file, a device name), and
the editor is driven through every path that shows text: open, run, problems, inspector, sub-graphs,
front panel, files, device panel, G-code export, notifications. Every markdown and HTML message viser
sends is recorded and checked, and a real Chromium page shows the text literally and runs no script.
"""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser
from pathlib import Path

import pytest
from viser import _messages
from viser.infra import _infra

import flowmc
from browser_helpers import chromium
from flowmc.devices.session import DeviceSession
from flowmc.ui.app import Editor
from flowmc.ui.text import escape_html, escape_md, md, plain, unescape_md

SCRIPT = '<iframe srcdoc="<script>top.__pwned=1;top.document.title=7</script>"></iframe>'
IMAGE = "![x](/etc/hostname)"
HOSTILE = (f"{SCRIPT}<img src=x onerror=\"top.__pwned=2\">{IMAGE}[link](javascript:top.__pwned=3)"
           "**bold** `code` <b>b</b> &lt;i&gt; | a | b |\n# heading\x1b[31m\x00")
FOLDER = "<img src=x onerror=top.__pwned=4>"  # a folder name can carry markup too (no slash)


# ---------------------------------------------------------------------------------------- the helpers
@pytest.mark.parametrize("text", [HOSTILE, FOLDER, "a\\b", "\\", "x_y*z", "1. item", "- item", "```", "www.example.com"])
def test_escaped_markdown_has_no_markup_left(text):
    out = escape_md(text)
    rest = re.sub(r"\\.", "", out)  # what remains when every backslash escape is taken out
    assert not set(rest) & set("<>[]()!`*_&|#\\"), rest
    assert "![" not in out and "\x1b" not in out and "\x00" not in out
    assert unescape_md(out) == plain(text)


def test_md_escapes_arguments_not_the_template():
    assert md("**{}** {:.2f} {n}", "<b>", 2.5, n="a_b") == "**\\<b\\>** 2\\.50 a\\_b"
    assert escape_html('<a href="x">&') == "&lt;a href=&quot;x&quot;&gt;&amp;"
    assert plain("a\x1b[0mb") == "a\\x1b[0mb" and len(plain("x" * 10_000)) == 4000


# ---------------------------------------------------------------------------------------- the sweep
def _hostile_folder(tmp_path: Path) -> tuple[Path, Path, Path]:
    folder = tmp_path / FOLDER
    folder.mkdir()
    (folder / "part.ngc").write_text(f"G1 X10 F600\n{HOSTILE}\n", encoding="utf-8")
    g = flowmc.GraphBuilder(title=HOSTILE, description=HOSTILE)
    g.add("path.gcode_in", id="gcode", file="part.ngc")
    runs = folder / "runs.flowmc.json"
    g.save(runs)
    doc = json.loads(runs.read_text())
    doc["nodes"] += [
        {"id": "weird", "type": HOSTILE, "params": {"p": HOSTILE}, "pos": [300, 0]},
        {"id": "table", "type": "path.segment_table", "pos": [0, 300],
         "params": {"rows": [{"type": HOSTILE, "end": [1, 0, 0]}], "feed": HOSTILE}},
        {"id": "sub", "type": "subgraph", "params": {"file": f"{FOLDER}.flowmc.json"}, "pos": [300, 300]},
        {"id": "num", "type": "basic.number", "params": {"value": 1}, "pos": [600, 0]},
    ]
    doc["interface"] = {"inputs": [{"name": "rate", "type": "Number", "description": HOSTILE, "to": ["num.value"]}],
                        "outputs": []}
    broken = folder / "broken.flowmc.json"
    broken.write_text(json.dumps(doc), encoding="utf-8")
    (folder / f"{FOLDER}.flowmc.json").write_text(HOSTILE, encoding="utf-8")
    return folder, runs, broken


class Recorder:
    """Every markdown, HTML and notification text viser is asked to send (to any client)."""

    def __init__(self, monkeypatch):
        self.markdown: list[str] = []
        self.html: list[str] = []
        self.plain: list[str] = []
        self._html_ids: set[str] = set()
        original = _infra.WebsockMessageHandler.queue_message

        def queue_message(handler, message):
            self.see(message)
            return original(handler, message)

        monkeypatch.setattr(_infra.WebsockMessageHandler, "queue_message", queue_message)

    def see(self, message) -> None:
        if isinstance(message, _messages.GuiMarkdownMessage):
            self.markdown.append(message.props._markdown)
        elif isinstance(message, _messages.GuiHtmlMessage):
            self._html_ids.add(message.uuid)
            self.html.append(message.props.content)
        elif isinstance(message, _messages.GuiUpdateMessage):
            if "_markdown" in message.updates:
                self.markdown.append(message.updates["_markdown"])
            if "content" in message.updates and message.uuid in self._html_ids:
                self.html.append(message.updates["content"])
            for key in ("label", "hint", "options"):
                if key in message.updates:
                    self.plain.append(str(message.updates[key]))
        elif isinstance(message, (_messages.NotificationShowMessage, _messages.NotificationUpdateMessage)):
            self.plain += [message.props.title, message.props.body]


class _ActiveParts(HTMLParser):
    """Collects what a browser would run or load from an HTML string: escaped text is not a tag."""

    ACTIVE_TAGS = {"script", "object", "embed", "base", "meta"}

    def __init__(self) -> None:
        super().__init__()
        self.found: list[str] = []

    def handle_starttag(self, tag, attrs):
        if tag in self.ACTIVE_TAGS:
            self.found.append(f"<{tag}>")
        own_view = "data-flowmc-port" in dict(attrs) and "src" not in dict(attrs)  # the page script points it at the 3D view
        if tag == "iframe" and not own_view:
            self.found.append("<iframe>")
        for name, value in attrs:
            if name.startswith("on") or name == "srcdoc":
                self.found.append(f"{tag} {name}=")
            if name in ("href", "src", "action") and (value or "").strip().lower().startswith("javascript:"):
                self.found.append(f"{tag} {name}={value}")


def _check_html(text: str) -> None:
    parser = _ActiveParts()
    parser.feed(text)
    parser.close()
    assert not parser.found, (parser.found, text)


def _check_markdown(text: str) -> None:
    rest = re.sub(r"\\.", "", text)
    assert "<" not in rest and "![" not in text and "](" not in rest and "`" not in rest, text
    assert "\x1b" not in text and "\x00" not in text, text


@pytest.mark.browser
def test_every_ui_path_shows_hostile_text_as_text(tmp_path, monkeypatch):
    folder, runs, broken = _hostile_folder(tmp_path)
    recorder = Recorder(monkeypatch)
    editor = Editor(runs, port=0, devices=DeviceSession())
    try:
        with chromium() as browser:
            page = browser.new_page(viewport={"width": 1600, "height": 1000})
            page.goto(editor.url)
            page.wait_for_function("window.__viserMutable?.nodeRefFromName?.['/canvas/body'] != null", timeout=30_000)
            # run: the G-code error quotes the hostile line (status line, notification, problems)
            editor.run()
            result = editor.wait()
            assert not result.ok and "<iframe" in str(result.errors)
            editor.select_node("gcode")
            # a graph with an unknown hostile node type, hostile params, a broken sub-graph, an interface
            assert editor.files.open(broken.name)
            for node_id in ("weird", "table", "sub", "num"):
                editor.select_node(node_id)
            editor.run()  # refused: the problems
            editor.extensions.front._changed("rate") if editor.extensions.front.controls else None
            # files: a hostile file that is not a graph, a hostile save-as name, a hostile upload
            editor.files.open(f"{FOLDER}.flowmc.json")
            editor.files.save_as(HOSTILE)
            editor.files.upload(f"{FOLDER}.flowmc.json", HOSTILE.encode(), None)
            editor.export_gcode()
            editor.extensions.device.connect(HOSTILE)
            editor.state.load(runs)
            editor.export_gcode()
            page.wait_for_timeout(1500)
            shown = page.inner_text("body")
            pwned = page.evaluate("window.__pwned")
            title = page.title()
            frames = page.evaluate("document.querySelectorAll('iframe[srcdoc]').length")
            images = page.evaluate("[...document.images].map(i => i.getAttribute('src'))")
            page.screenshot(path=str(tmp_path / "hostile.png"))
    finally:
        editor.close()
    # the page ran nothing and loaded no image, and shows the text itself
    assert pwned is None and title != "7" and frames == 0, (pwned, title, frames)
    assert not [s for s in images if s and (s == "x" or s.startswith("data:image/png"))], images
    assert "<iframe srcdoc=" in shown and FOLDER in shown
    # every markdown and HTML message was escaped, and the hostile text reached many of them
    for text in recorder.markdown:
        _check_markdown(text)
    for text in recorder.html:
        _check_html(text)
    for text in recorder.plain:
        assert "\x1b" not in text and "\x00" not in text, text
    reached = [t for t in recorder.markdown if "iframe srcdoc" in unescape_md(t) or FOLDER in unescape_md(t)]
    assert len(reached) >= 8, reached
    noted = [t for t in recorder.plain if "iframe" in t or "img src" in t]
    assert len(noted) >= 3, recorder.plain
