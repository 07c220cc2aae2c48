"""Editor responsiveness in a real browser (Debian's chromium, software WebGL on this machine).

- click -> visible change: a click on a node until its frame shows the selection colour in the
  scene and one more frame has been drawn, timed inside the page (from the pointerdown event);
  median of N clicks alternating between nodes. Also the time until the inspector shows the node.
- open: ``page.goto`` until every node of a 100-node graph is in the scene (and the camera is set).

Run: ``python3 benchmarks/editor.py [--clicks 15] [--opens 3]``. Prints a table with the targets.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "ui")]

from browser_helpers import EditorPage, chromium, expected  # noqa: E402
from editor_graphs import chain_file, example_file  # noqa: E402
from flowmc.ui import canvas_draw  # noqa: E402
from flowmc.ui.app import Editor  # noqa: E402

CLICK_TARGET_MS = 100.0
OPEN_TARGET_S = 3.0

_ARM = """() => { window.__flowmcClick = null;
  window.__viserMutable.canvas.addEventListener('pointerdown', () => { window.__flowmcClick = performance.now(); },
                                                 { capture: true, once: true }); }"""

_WAIT_SELECTED = """([index, red, text]) => new Promise(resolve => {
  const frameOf = () => { const o = window.__viserMutable.nodeRefFromName['/canvas/frame']; let m = null;
    o.traverse(c => { if (c.isInstancedMesh && !m) m = c; }); return m; };
  let scene = null, dom = null;
  const poll = () => {
    const now = performance.now(), m = frameOf();
    if (scene === null && m && index < (m.instancesCount ?? m.count)) {
      const c = new (m.material.color.constructor)(); m.getColorAt(index, c);
      if (Math.abs(c.r - red) < 0.01) scene = now;
    }
    if (dom === null && document.body.innerText.includes(text)) dom = now;
    if (scene !== null && dom !== null) {
      requestAnimationFrame(() => resolve([scene, performance.now(), dom, window.__flowmcClick]));
    } else if (now - window.__flowmcClick > 10000) { resolve(null); } else { requestAnimationFrame(poll); }
  };
  requestAnimationFrame(poll);
})"""


def click_latencies(ui: EditorPage, node_ids: list[str], clicks: int) -> tuple[list[float], list[float]]:
    """(scene ms, inspector ms) per click: pointerdown -> selection colour drawn / node shown in the panel."""
    red = float(expected(canvas_draw.FRAME_SELECTED)[0])
    order = [n.id for n in ui.editor.state.graph.nodes]
    scene_ms, panel_ms = [], []
    for k in range(clicks):
        node_id = node_ids[k % len(node_ids)]
        ui.page.evaluate(_ARM)
        ui.click_node(node_id)
        got = ui.page.evaluate(_WAIT_SELECTED, [order.index(node_id), red, f"{node_id} ·"])
        if got is None:
            raise RuntimeError(f"click {k} on {node_id}: no visible change within 10 s")
        seen, drawn, shown, clicked = got
        scene_ms.append(drawn - clicked)
        panel_ms.append(shown - clicked)
        ui.page.wait_for_timeout(150)
    return scene_ms, panel_ms


def open_times(browser, editor: Editor, opens: int) -> list[float]:
    times = []
    for _ in range(opens):
        ui = EditorPage(browser, editor)
        times.append(ui.open(timeout=60))
        ui.page.close()
    return times


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clicks", type=int, default=15)
    parser.add_argument("--opens", type=int, default=3)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp, chromium() as browser:
        small = Editor(example_file(Path(tmp)), port=0)
        try:
            ui = EditorPage(browser, small)
            ui.open()
            ui.dismiss_toasts()
            scene, panel = click_latencies(ui, ["shift", "table", "both", "edge"], args.clicks)
            ui.page.close()
        finally:
            small.close()
        rows.append(("click -> selection drawn, 4-node graph", statistics.median(scene), "ms", CLICK_TARGET_MS, scene))
        rows.append(("click -> inspector shows node, 4-node graph", statistics.median(panel), "ms", None, panel))

        start = time.perf_counter()
        big = Editor(chain_file(Path(tmp), 100), port=0)
        startup = time.perf_counter() - start
        try:
            opened = open_times(browser, big, args.opens)
            ui = EditorPage(browser, big)
            ui.open(timeout=60)
            ui.dismiss_toasts()
            scene100, _ = click_latencies(ui, ["t45", "t12", "t78", "p30"], max(5, args.clicks // 2))
            ui.page.close()
        finally:
            big.close()
        rows.append(("open 100-node graph (goto -> all nodes in scene)", statistics.median(opened), "s", OPEN_TARGET_S, opened))
        rows.append(("editor start on 100-node graph (Python side)", startup, "s", None, [startup]))
        rows.append(("click -> selection drawn, 100-node graph", statistics.median(scene100), "ms", None, scene100))

    print("\nflowmc editor benchmark (chromium, software WebGL; medians)\n")
    print(f"{'measure':<52} {'median':>10} {'target':>10} {'ok':>4}   {'n':>3}  {'min':>8} {'max':>8}")
    failed = False
    for name, value, unit, target, samples in rows:
        fmt = (lambda v: f"{v:.0f} ms") if unit == "ms" else (lambda v: f"{v:.2f} s")
        ok = "" if target is None else ("yes" if value <= target else "NO")
        failed |= ok == "NO"
        print(f"{name:<52} {fmt(value):>10} {(fmt(target) if target else '-'):>10} {ok:>4}   {len(samples):>3}"
              f"  {fmt(min(samples)):>8} {fmt(max(samples)):>8}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
