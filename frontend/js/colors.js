// @ts-check
// LED colours: one colour for the selection, a gradient across it, or colours taken from an image
// laid over the selection's bounding box in the current view.

import { VIEW_AXES, centroid } from "./geometry.js";

/**
 * `#rrggbb` -> [r, g, b] (0-255).
 * @param {string} hex
 * @returns {number[]}
 */
export function hexToRgb(hex) {
  const v = parseInt(hex.slice(1), 16);
  return [(v >> 16) & 255, (v >> 8) & 255, v & 255];
}

/**
 * [r, g, b] (0-255) -> `#rrggbb`.
 * @param {number[]} rgb
 * @returns {string}
 */
export function rgbToHex(rgb) {
  return `#${rgb.map((c) => Math.max(0, Math.min(255, Math.round(c))).toString(16).padStart(2, "0")).join("")}`;
}

/**
 * Mix two colours.
 * @param {string} a @param {string} b @param {number} t 0..1
 * @returns {string}
 */
export function mix(a, b, t) {
  const ca = hexToRgb(a);
  const cb = hexToRgb(b);
  return rgbToHex(ca.map((c, k) => c + (cb[k] - c) * t));
}

/**
 * The indices an action applies to: the selection, or every point when nothing is selected.
 * @param {import("./state.js").EditorState} state
 * @returns {number[]}
 */
export function targetIndices(state) {
  const f = state.formation;
  if (!f) return [];
  return state.selection.size ? [...state.selection].sort((a, b) => a - b) : f.points.map((_, i) => i);
}

/**
 * Colour the selection (or the whole formation).
 * @param {import("./state.js").EditorState} state
 * @param {string} color `#rrggbb`
 */
export function applyColor(state, color) {
  const idx = targetIndices(state);
  if (!idx.length) return;
  state.edit(`Colour ${idx.length} points`, () => {
    const f = state.formation;
    for (const i of idx) f.colors[i] = color;
  });
}

/**
 * A gradient from `a` to `b` across the selection.
 * @param {import("./state.js").EditorState} state
 * @param {string} a start colour
 * @param {string} b end colour
 * @param {"h"|"v"|"order"|"radial"} direction left->right, bottom->top (in the view), point order, centre->out
 * @param {string} view a key of VIEW_AXES
 */
export function applyGradient(state, a, b, direction, view) {
  const idx = targetIndices(state);
  if (!idx.length) return;
  const f = state.formation;
  const [u, v] = VIEW_AXES[view];
  let key;
  if (direction === "order") key = (_i, k) => k;
  else if (direction === "radial") {
    const c = centroid(f.points, idx);
    key = (i) => Math.hypot(f.points[i][u] - c[u], f.points[i][v] - c[v]);
  } else {
    const axis = direction === "h" ? u : v;
    key = (i) => f.points[i][axis];
  }
  const keys = idx.map((i, k) => key(i, k));
  const lo = Math.min(...keys);
  const hi = Math.max(...keys);
  state.edit(`Gradient on ${idx.length} points`, () => {
    idx.forEach((i, k) => {
      f.colors[i] = mix(a, b, hi > lo ? (keys[k] - lo) / (hi - lo) : 0);
    });
  });
}

/**
 * Colour the selection from an image stretched over its bounding box in the view
 * (transparent pixels leave the colour unchanged).
 * @param {import("./state.js").EditorState} state
 * @param {Blob} file a PNG or JPEG
 * @param {string} view a key of VIEW_AXES
 * @returns {Promise<number>} how many points were coloured
 */
export async function colorsFromImage(state, file, view) {
  const idx = targetIndices(state);
  if (!idx.length) return 0;
  let bitmap;
  try {
    bitmap = await createImageBitmap(file);
  } catch {
    throw new Error("cannot read this image (PNG or JPEG expected)");
  }
  const w = Math.min(bitmap.width, 1024);
  const h = Math.max(1, Math.round((bitmap.height * w) / bitmap.width));
  const canvas = new OffscreenCanvas(w, h);
  const ctx = canvas.getContext("2d");
  ctx.drawImage(bitmap, 0, 0, w, h);
  const data = ctx.getImageData(0, 0, w, h).data;
  const f = state.formation;
  const [u, v] = VIEW_AXES[view];
  const us = idx.map((i) => f.points[i][u]);
  const vs = idx.map((i) => f.points[i][v]);
  const [u0, u1, v0, v1] = [Math.min(...us), Math.max(...us), Math.min(...vs), Math.max(...vs)];
  let count = 0;
  state.edit(`Colours from image on ${idx.length} points`, () => {
    idx.forEach((i, k) => {
      const px = Math.min(w - 1, Math.max(0, Math.round(u1 > u0 ? ((us[k] - u0) / (u1 - u0)) * (w - 1) : w / 2)));
      const py = Math.min(h - 1, Math.max(0, Math.round(v1 > v0 ? ((v1 - vs[k]) / (v1 - v0)) * (h - 1) : h / 2)));
      const o = (py * w + px) * 4;
      if (data[o + 3] < 128) return;
      f.colors[i] = rgbToHex([data[o], data[o + 1], data[o + 2]]);
      count++;
    });
    return count > 0;
  });
  return count;
}
