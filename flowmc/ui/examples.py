"""The examples browser: the example graphs that come with flowmc, each with its title, what it shows
and an Open button. It lists them whatever folder the editor serves; an example opens where it
lives (so its pictures and library graphs are found) and is saved into the editor's folder with
Save as (the Files tab refuses to overwrite it in place).

The list is one HTML element (its Open buttons send the page event ``example-open`` with the file
name), not a viser folder, markdown and button per example: every page that opens the editor is
sent the tab's contents, and that was 42 GUI messages of the first frame's.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from flowmc.errors import GraphError
from flowmc.graph import load
from flowmc.ui.palette_list import button_css, page_button
from flowmc.ui.text import escape_html

if TYPE_CHECKING:
    from flowmc.ui.session import PanelHost

__all__ = ["ExamplesPanel", "examples_dir", "example_files", "OPEN_EVENT"]

SUFFIX = ".flowmc.json"
OPEN_EVENT = "example-open"
_STYLE = ("<style>.flowmc-examples section{margin:0 var(--mantine-spacing-xs) .9em;padding-bottom:.6em;"
          "border-bottom:1px solid var(--mantine-color-default-border)}"
          ".flowmc-examples h4{margin:0 0 .2em;font-size:.95em;font-weight:600}"
          ".flowmc-examples p{margin:0 0 .45em;font-size:.85em;opacity:.8}"
          ".flowmc-examples button{padding:0 .9em}" + button_css(".flowmc-examples", "primary-color") + "</style>")


def examples_dir() -> Path | None:
    """Where the example graphs are: inside the installed package, else the source tree's ``graphs/``."""
    for candidate in (resources.files("flowmc") / "examples", Path(str(resources.files("flowmc"))).parent / "graphs"):
        path = Path(str(candidate))
        if path.is_dir() and any(path.glob(f"*{SUFFIX}")):
            return path
    return None


def example_files() -> list[tuple[Path, str, str]]:
    """(file, title, first line of its description) of every example graph, by file name."""
    folder = examples_dir()
    out = []
    for path in sorted(folder.glob(f"*{SUFFIX}")) if folder is not None else []:
        try:
            graph = load(path)
        except GraphError:
            continue
        about = (graph.description.strip().splitlines() or [""])[0]
        out.append((path, graph.title or path.name[: -len(SUFFIX)], about))
    return out


def render(found: list[tuple[Path, str, str]]) -> str:
    """The list's HTML: per example its title, what it shows and its Open button."""
    parts = [_STYLE, '<div class="flowmc-examples">']
    for path, title, about in found:
        parts.append(f"<section><h4>{escape_html(title, 200)}</h4><p>{escape_html(about or path.name, 600)}</p>"
                     + page_button(OPEN_EVENT, path.name, f"Open {path.name[: -len(SUFFIX)]}", str(path)) + "</section>")
    parts.append("</div>")
    return "".join(parts)


class ExamplesPanel:
    """Every example in one list (built in the current container); ``files`` by file name."""

    def __init__(self, host: "PanelHost"):
        self.host = host
        found = example_files()
        self.files = {path.name: path for path, _title, _about in found}
        if found:
            host.gui.add_html(render(found))
        else:
            host.gui.add_markdown("No example graphs were found in this installation.")

    def picked(self, name: Any, client: Any = None) -> None:
        """The Open button of the example file ``name`` was clicked (a name not listed is ignored)."""
        path = self.files.get(name) if isinstance(name, str) else None
        if path is not None:
            self.open(path, client)

    def open(self, path: Path, client: Any = None) -> None:
        state = self.host.session.state

        def go() -> None:
            try:
                state.load(path)
            except GraphError as exc:
                self.host.notify("error", str(exc))
                return
            self.host.notify("info", f"opened the example {path.name}: Save as keeps a copy in your folder")

        if state.dirty:
            self.host.confirm("Unsaved changes", "The open graph has unsaved changes. Discard them?", "Discard changes",
                              go, client)
        else:
            go()
