"""What a canvas frame costs the page under software WebGL, cut where nobody sees the work.

Without a GPU every frame is drawn on the CPU, and the page's main thread waits for it: a 120-node
frame took 450-700 ms on the shared 2-core machine, and a side-panel update that arrives meanwhile
waits behind it. viser draws its background-image quad over the whole view in every frame, with a
shader that samples an image and writes depth, even when no background image is set: about a
fifth of the frame (measured by timing ``renderer.render`` with it shown and hidden). The page
script here hides that quad while no image is set (flowmc sets none) and shows it again if one is.

While a frame is being drawn the page takes no message: the editor's answer to a click waited behind a
frame drawn for the click itself (viser's drag layer asks for one on press and release, though nothing
on screen changes) and behind the hover outline's frame. So frames asked for between a press on the
canvas and the editor's answer (the first frame a server message asks for) wait for that answer, at
most ``HOLD_MS``, and then ``ANSWER_MS`` more: the side panel's text, which viser applies with the
same messages, reaches the page before the frame takes the thread. A drag or a pan draws at once.
A hover outline is drawn ``HOVER_MS`` late, or with the click's answer when a press comes first.
"""

from __future__ import annotations

from typing import Any

from flowmc.ui import viser_internals

__all__ = ["install", "HOLD_MS", "HOVER_MS"]

HOLD_MS = 400  # longest a press holds the frames back (the editor answers a click in tens of ms when not loaded)
HOVER_MS = 150
ANSWER_MS = 50  # the answer's frame waits this long, so that the page shows the side panel's text first

_JS = """
(function flowmcFrames() {
  const m = window.__viserMutable;
  if (!m || window.__flowmcFramesInstalled) return;
  window.__flowmcFramesInstalled = true;
  const check = () => {
    const mat = m.backgroundMaterial, scene = m.scene;
    const quad = mat && scene && scene.children.find(o => o.isMesh && o.material === mat);
    if (!quad) return;
    const wanted = !!(mat.uniforms && mat.uniforms.enabled && mat.uniforms.enabled.value);
    if (quad.visible !== wanted) { quad.visible = wanted; if (m.requestRender) m.requestRender(); }
  };
  check();
  setInterval(check, 1000);

  // Frames held from a press on the canvas until the editor's answer. viser asks for frames through
  // requestRender and also from inside its own code, so the hold is kept where frames are drawn.
  const real = m.requestRender;
  if (!real || !m.canvas || !m.scene) return;
  const st = window.__flowmcFrames = { until: 0, held: 0, drawn: 0, hover: null, at: null, answered: false };
  const release = () => { if (st.until) { st.until = 0; real(); } };  // the frame: everything held, drawn at once
  m.requestRender = function () {
    const e = window.event;
    if (st.until && e && e.type === "message") {  // the answer: its side-panel text goes into the page first
      if (!st.answered) { st.answered = true; st.until = performance.now() + ANSWER_MS; setTimeout(release, ANSWER_MS + 5); }
      return;
    }
    if (!st.until && e && e.type === "pointermove" && !e.buttons) {  // a hover outline, a moment later
      if (!st.hover) st.hover = setTimeout(() => { st.hover = null; if (!st.until) real(); }, HOVER_MS);
      return;
    }
    return real.apply(this, arguments);
  };
  const hook = (renderer) => {
    const draw = renderer.render;
    renderer.render = function (scene) {
      if (scene === m.scene && st.until && performance.now() < st.until) { st.held += 1; return; }
      if (scene === m.scene) st.drawn += 1;  // frames really drawn (benchmarks/editor.py waits for one)
      return draw.apply(this, arguments);
    };
  };
  const before = m.scene.onBeforeRender;
  m.scene.onBeforeRender = function (renderer) {  // the renderer, once, from inside its first frame
    m.scene.onBeforeRender = before; hook(renderer); return before.apply(this, arguments);
  };
  real();
  m.canvas.addEventListener("pointerdown", (e) => {
    if (e.button !== 0) return;
    st.until = performance.now() + HOLD_MS; st.at = [e.clientX, e.clientY]; st.answered = false;
    if (st.hover) { clearTimeout(st.hover); st.hover = null; }  // the outline comes with the answer's frame
    setTimeout(() => { if (st.until && performance.now() >= st.until) release(); }, HOLD_MS + 5);
  }, true);
  window.addEventListener("pointermove", (e) => {  // a drag or a pan draws as it goes
    if (st.until && st.at && Math.hypot(e.clientX - st.at[0], e.clientY - st.at[1]) > 3) release();
  }, true);
})();
""".replace("HOLD_MS", str(HOLD_MS)).replace("HOVER_MS", str(HOVER_MS)).replace("ANSWER_MS", str(ANSWER_MS))


def install(client: Any) -> None:
    """In ``client``'s page: the background-image quad hidden while it shows no image, frames held from a
    press on the canvas until the editor answers, hover outlines drawn a moment late."""
    viser_internals.run_js(client, _JS)
