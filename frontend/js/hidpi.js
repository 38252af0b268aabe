// @ts-check
// Sharp canvases on high-DPI screens: the backing store follows the canvas' CSS box times the device
// pixel ratio, and the 2D context is scaled so that callers draw in CSS pixels.

/**
 * Fit `c`'s backing store to its CSS size times `dpr`, then hand back its 2D context scaled to CSS
 * pixels and cleared. The store is reassigned only when its size changes, since assigning a canvas'
 * width or height clears it and reallocates its memory.
 * @param {HTMLCanvasElement} c
 * @param {number} [dpr] device pixels per CSS pixel
 * @returns {{g: CanvasRenderingContext2D, w: number, h: number} | null} the context and the CSS size;
 *   null while the canvas has no size (hidden: nothing to draw)
 */
export function fitCanvas(c, dpr = globalThis.devicePixelRatio || 1) {
  const w = c.clientWidth;
  const h = c.clientHeight;
  if (!w || !h) return null;
  if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) {
    c.width = Math.round(w * dpr);
    c.height = Math.round(h * dpr);
  }
  const g = /** @type {CanvasRenderingContext2D} */ (c.getContext("2d"));
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  g.clearRect(0, 0, w, h);
  return { g, w, h };
}
