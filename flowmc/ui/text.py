"""The one way text reaches the editor page: graph, G-code, file and error text is never markup.

viser renders ``add_markdown`` content as GitHub markdown with raw HTML passed through unsanitised
(script included), reads ``![..](path)`` images from the server's disk into data URLs, and puts
``add_html`` content into the page as is. So every string flowmc did not write itself goes through
one of these before it reaches a markdown or HTML element:

- ``escape_md(s)``: shows ``s`` literally in markdown (every ASCII punctuation character is
  backslash-escaped, which CommonMark defines for exactly this; no ``<``, ``![`` or ``](`` survives);
- ``md(template, *args)``: ``template.format`` with every argument escaped (the template is flowmc's);
- ``escape_html(s)``: shows ``s`` literally in HTML;
- ``plain(s)``: for places viser shows as text (labels, hints, notifications, titles, options).

All four make control characters visible (``\\x1b``) and cut very long text.
"""

from __future__ import annotations

import html
import re
from typing import Any

from flowmc.errors import printable

__all__ = ["escape_md", "escape_html", "md", "plain", "unescape_md", "MAX_TEXT"]

MAX_TEXT = 4000  # characters of one piece of text shown on the page
_PUNCTUATION = re.compile(r"([!-/:-@\[-`{-~])")  # ASCII punctuation: CommonMark can escape every one
_ESCAPED = re.compile(r"\\([!-/:-@\[-`{-~])")


def plain(text: Any, limit: int | None = MAX_TEXT) -> str:
    """Text for a place the page shows as text (not markdown): control characters made visible, cut."""
    return printable(text, limit)


def escape_md(text: Any, limit: int | None = MAX_TEXT) -> str:
    """``text`` shown literally inside markdown: no emphasis, link, image, HTML, heading or table."""
    s = plain(text, limit).replace("\r\n", "\n")
    return _PUNCTUATION.sub(r"\\\1", s)


def unescape_md(markdown: str) -> str:
    """``markdown`` with backslash escapes undone: the text a reader sees, markup marks kept
    (tests compare it with what they expect; ``unescape_md(escape_md(s)) == s`` for printable ``s``)."""
    return _ESCAPED.sub(r"\1", markdown)


def escape_html(text: Any, limit: int | None = MAX_TEXT) -> str:
    """``text`` shown literally inside HTML (element content or a quoted attribute)."""
    return html.escape(plain(text, limit), quote=True)


def md(template: str, *args: Any, **kwargs: Any) -> str:
    """``template.format(...)`` with every argument passed through ``escape_md`` (format specs such
    as ``{:.2f}`` apply to numbers before escaping). The template itself is flowmc's own markdown."""
    return template.format(*map(_Arg, args), **{k: _Arg(v) for k, v in kwargs.items()})


class _Arg:
    """One argument of ``md``: formatted with its spec (``{:.2f}``), then escaped."""

    __slots__ = ("value",)

    def __init__(self, value: Any):
        self.value = value

    def __format__(self, spec: str) -> str:
        return escape_md(format(self.value, spec))
