"""The palette's entries as one HTML element: a folder per category (``<details>``, open), a button per
entry with its description and ports as the tooltip.

One element instead of a viser folder per category and a viser button (with its tooltip) per entry:
a page opening the editor built those ~66 Mantine buttons in the frame that applies the server's
first messages, the largest part of that frame (docs/architecture.md, "Where an open's time goes").
Here the browser parses one string. The page script (``viser_internals``) sends a click on an entry as
the page event ``palette-add`` (``page_button``) and an entry dragged onto the canvas as ``palette-drop``,
both with the entry's ``PaletteItem.key``. Every text from a node type or a graph file is
escaped (``escape_html``): a graph file's title is never markup.
"""

from __future__ import annotations

from flowmc.ui.palette import PaletteItem
from flowmc.ui.text import escape_html

__all__ = ["render", "labels", "page_button", "button_css", "ADD_EVENT"]

ADD_EVENT = "palette-add"  # the page script also drags the buttons that send it


def button_css(scope: str, colour: str) -> str:
    """The look of ``page_button`` buttons inside ``scope`` (a CSS selector): filled with the theme's
    ``colour`` (``color-gray``, ``primary-color``), as viser's own buttons are."""
    return (f"{scope} button{{height:2em;border:0;border-radius:var(--mantine-radius-default);"
            f"background:var(--mantine-{colour}-filled);color:#fff;font:inherit;font-size:var(--mantine-font-size-sm);"
            f"font-weight:500;cursor:pointer}}{scope} button:hover{{background:var(--mantine-{colour}-filled-hover)}}")


# Looks like viser's own folders (a border with the title on it) and gray buttons, in the theme's colours.
_STYLE = (
    "<style>"
    ".flowmc-palette details{position:relative;border:1px solid var(--mantine-color-default-border);"
    "border-radius:var(--mantine-radius-default);margin:1em var(--mantine-spacing-xs) .25em;padding:.9em .5em .05em}"
    ".flowmc-palette summary{position:absolute;top:0;left:.375em;transform:translateY(-50%);padding:0 .375em;"
    "font-size:.875em;font-weight:500;background:var(--mantine-color-body);cursor:pointer;user-select:none;"
    "list-style:none}"
    ".flowmc-palette summary::-webkit-details-marker{display:none}"
    ".flowmc-palette summary::after{content:'';display:inline-block;width:.35em;height:.35em;margin:0 .1em .1em .5em;"
    "border:solid currentColor;border-width:0 2px 2px 0;opacity:.5;transform:rotate(-135deg);vertical-align:.05em}"
    ".flowmc-palette details:not([open]){padding-bottom:.4em}"
    ".flowmc-palette details:not([open]) summary::after{transform:rotate(45deg);vertical-align:.2em}"
    ".flowmc-palette button{display:block;width:100%;margin:0 0 .4em;padding:0 .75em;white-space:nowrap;"
    "overflow:hidden;text-overflow:ellipsis;touch-action:none}"
    ".flowmc-palette button:focus-visible{outline:2px solid var(--mantine-primary-color-filled);outline-offset:1px}"
    + button_css(".flowmc-palette", "color-gray") + "</style>"
)


def labels(items: list[PaletteItem]) -> list[str]:
    """Each entry's button text: its title, with its category where an earlier entry has the same title."""
    seen: set[str] = set()
    out = []
    for item in items:
        out.append(item.title if item.title not in seen else f"{item.title} ({item.category})")
        seen.add(item.title)
    return out


def page_button(event: str, key: str, label: str, tip: str = "") -> str:
    """A button whose click the page script sends as the page event ``event`` with ``{"key": key}``
    (``data-flowmc-send``, ``data-flowmc-key``); ``tip`` shows on hover."""
    return (f'<button type="button" data-flowmc-send="{escape_html(event)}" data-flowmc-key="{escape_html(key, 400)}"'
            f' title="{escape_html(tip)}">{escape_html(label, 120)}</button>')


def _entry(item: PaletteItem, label: str) -> str:
    return page_button(ADD_EVENT, item.key, label, item.description + (f"\n{item.ports}" if item.ports else ""))


def render(groups: dict[str, list[PaletteItem]]) -> str:
    """The list's HTML: one open folder per group (a category, or the matches of a search) in the given order."""
    parts = [_STYLE, '<div class="flowmc-palette">']
    for name, items in groups.items():
        parts.append(f"<details open><summary>{escape_html(name, 80)}</summary>")
        parts += [_entry(item, label) for item, label in zip(items, labels(items))]
        parts.append("</details>")
    parts.append("</div>")
    return "".join(parts)
