"""Canvas screenshots of every example graph after auto-layout, for docs/screenshots/ and the README.

Each example opens in a fresh editor (on a copy, so the example itself is not touched) in Debian's
chromium; the Layout button lays it out and frames it, and the canvas part of the page is saved as
``docs/screenshots/<name>.png``. The table printed says, per graph, how many nodes overlap after
the layout (should be 0) and how tall a node title is on screen at that Fit (13 canvas px at zoom 1;
below about 8 px it is hard to read). Exits 1 when something overlaps.

Run: ``python3 scripts/screenshots.py [--out docs/screenshots] [NAME ...]``.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "ui")]

from PIL import Image  # noqa: E402

from browser_helpers import EditorPage, chromium, wait_until  # noqa: E402
from flowmc.ui import arrange, camera, layout  # noqa: E402
from flowmc.ui.app import Editor  # noqa: E402
from flowmc.ui.examples import SUFFIX  # noqa: E402

COLOURS = 256  # the saved PNGs are palette images: a third of the size, no visible loss on flat shapes


def shoot(browser, source: Path, out: Path) -> tuple[int, int, float]:
    """(nodes, overlapping pairs, on-screen title height in px) for one graph; writes its screenshot."""
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(source.parent, tmp, dirs_exist_ok=True)
        editor = Editor(Path(tmp) / source.name, port=0, extensions=False)
        try:
            ui = EditorPage(browser, editor)
            ui.open(timeout=60)
            ui.page.add_style_tag(content=".mantine-Notifications-root { display: none !important; }")  # WebGL notice
            ui.page.get_by_role("button", name="Layout", exact=True).click()
            boxes = lambda: editor.actions.rects([b.node_id for b in editor.canvas.boxes])  # noqa: E731
            wait_until(lambda: not arrange.overlaps(boxes()), 30, "the layout")
            ui.settled()
            ui.page.wait_for_timeout(1500)
            rect = ui.page.evaluate("(() => { const r = window.__viserMutable.canvas.getBoundingClientRect(); "
                                    "return {x: r.left, y: r.top, width: r.width, height: r.height}; })()")
            png = out / f"{source.name.removesuffix(SUFFIX)}.png"
            ui.page.screenshot(path=str(png), clip=rect)
            Image.open(png).convert("RGB").quantize(COLOURS, method=Image.Quantize.FASTOCTREE).save(png, optimize=True)
            client = next(iter(editor.server.get_clients().values()))
            per_world = camera.screen_px_per_world(client.camera) or 0.0
            title_px = layout.TITLE_FONT * layout.SCALE * per_world
            ui.page.close()
            return len(editor.canvas.boxes), len(arrange.overlaps(boxes())), title_px
        finally:
            editor.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "screenshots")
    parser.add_argument("names", nargs="*", help="example names (default: all of graphs/)")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    graphs = sorted((ROOT / "graphs").glob(f"*{SUFFIX}"))
    if args.names:
        graphs = [g for g in graphs if g.name.removesuffix(SUFFIX) in args.names]
    rows = []
    with chromium() as browser:
        for graph in graphs:
            rows.append((graph.name.removesuffix(SUFFIX), *shoot(browser, graph, args.out)))
    print(f"\n{'graph':<22} {'nodes':>6} {'overlaps':>9} {'title px at Fit':>16}")
    for name, nodes, overlaps, title_px in rows:
        print(f"{name:<22} {nodes:>6} {overlaps:>9} {title_px:>16.1f}")
    return 1 if any(r[2] for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
