"""What a canvas frame costs the page under software WebGL, cut where nobody sees the work.

Without a GPU every frame is drawn on the CPU, and the page's main thread waits for it: a 120-node
frame took 450-700 ms on the shared 2-core machine, and a side-panel update that arrives meanwhile
waits behind it. viser draws its background-image quad over the whole view in every frame, with a
shader that samples an image and writes depth, even when no background image is set: about a
fifth of the frame (measured by timing ``renderer.render`` with it shown and hidden). The page
script here hides that quad while no image is set (flowmc sets none) and shows it again if one is.
"""

from __future__ import annotations

from typing import Any

from flowmc.ui import viser_internals

__all__ = ["install"]

_JS = """
(function flowmcBackgroundQuad() {
  const m = window.__viserMutable;
  if (!m || window.__flowmcBackgroundQuad) return;
  window.__flowmcBackgroundQuad = true;
  const check = () => {
    const mat = m.backgroundMaterial, scene = m.scene;
    const quad = mat && scene && scene.children.find(o => o.isMesh && o.material === mat);
    if (!quad) return;
    const wanted = !!(mat.uniforms && mat.uniforms.enabled && mat.uniforms.enabled.value);
    if (quad.visible !== wanted) { quad.visible = wanted; if (m.requestRender) m.requestRender(); }
  };
  check();
  setInterval(check, 1000);
})();
"""


def install(client: Any) -> None:
    """Keep the background-image quad of ``client``'s page hidden while it shows no image."""
    viser_internals.run_js(client, _JS)
