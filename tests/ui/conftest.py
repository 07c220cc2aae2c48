"""What the editor tests share: one Chromium per test module, and editors that close after their test."""

from __future__ import annotations

from typing import Any, Callable, Iterator

import pytest

from browser_helpers import chromium


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """Debian's chromium driven by playwright, one per test module."""
    with chromium() as b:
        yield b


@pytest.fixture
def open_editor() -> Iterator[Callable[..., Any]]:
    """``open_editor(graph_file, **options)``: an ``Editor`` on a free port, closed when the test ends."""
    from flowmc.ui.app import Editor

    opened: list[Editor] = []

    def open_(path: Any, **options: Any) -> Editor:
        opened.append(Editor(path, **{"port": 0, **options}))
        return opened[-1]

    yield open_
    for editor in reversed(opened):
        editor.close()
