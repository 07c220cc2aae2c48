"""The examples browser: the example graphs that come with flowmc, each with its title, what it shows
and an Open button. It lists them whatever folder the editor serves; an example opens where it
lives (so its pictures and library graphs are found) and is saved into the editor's folder with
Save as (the Files tab refuses to overwrite it in place).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from flowmc.errors import GraphError
from flowmc.graph import load
from flowmc.ui.text import escape_md

if TYPE_CHECKING:
    from flowmc.ui.session import PanelHost

__all__ = ["ExamplesPanel", "examples_dir", "example_files"]

SUFFIX = ".flowmc.json"


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


class ExamplesPanel:
    """One entry per example (built in the current container); ``buttons`` by file name."""

    def __init__(self, host: "PanelHost"):
        self.host = host
        gui = host.gui
        self.buttons: dict[str, Any] = {}
        found = example_files()
        if not found:
            gui.add_markdown("No example graphs were found in this installation.")
        for path, title, about in found:
            with gui.add_folder(title, expand_by_default=True):
                gui.add_markdown(escape_md(about or path.name))
                button = gui.add_button(f"Open {path.name[: -len(SUFFIX)]}", hint=str(path))
                button.on_click(lambda e, p=path: self.open(p, e.client))
                self.buttons[path.name] = button

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
