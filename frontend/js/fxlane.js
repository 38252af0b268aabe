// @ts-check
// The effect lane under the music lane (issue 18): each light effect's time range as a bar on the
// music lane's time axis. Drag a bar's end to move its start or end (snapping to the beats or onsets
// the music lane snaps to; Shift: freely); click a bar to edit its effect.

import { fitCanvas } from "./hidpi.js";
import { snapTime } from "./musicmath.js";

/** Grab distance of a bar's end, CSS pixels. */
const GRAB_PX = 6;
/** Snap distance to a beat, CSS pixels (as the cue markers'). */
const SNAP_PX = 10;
/** Most rows the bars are spread over. */
const MAX_ROWS = 3;
/** Shortest effect a drag leaves, seconds. */
const MIN_LENGTH_S = 0.05;

export class EffectLane {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {{span: () => number, snapPoints: () => number[], time_s: number}} music the music lane (time axis,
   *   snap points, playhead)
   * @param {import("./effects.js").EffectsPanel} effects the effects panel (selection, one-step edits)
   */
  constructor(state, music, effects) {
    this.state = state;
    this.music = music;
    this.effects = effects;
    this.canvas = /** @type {HTMLCanvasElement} */ (document.getElementById("fx-lane"));
    /** @type {{k: number, end: "start_s"|"end_s", t: number, moved?: boolean}|null} */
    this._drag = null;
    this.canvas.addEventListener("pointerdown", (e) => this._down(e));
    this.canvas.addEventListener("pointermove", (e) => this._move(e));
    this.canvas.addEventListener("pointerup", (e) => this._up(e));
    state.addEventListener("change", (/** @type {CustomEvent} */ e) => {
      if (e.detail.kind !== "live") this.draw();
    });
    new ResizeObserver(() => this.draw()).observe(this.canvas);
  }

  /** @param {number} t */
  _x(t) {
    return (t / this.music.span()) * this.canvas.clientWidth;
  }

  /** @param {number} x */
  _t(x) {
    return (x / Math.max(1, this.canvas.clientWidth)) * this.music.span();
  }

  get _rows() {
    return Math.max(1, Math.min(MAX_ROWS, this.effects.effects.length));
  }

  /**
   * Where effect k's bar is drawn, CSS pixels.
   * @param {number} k
   * @returns {{x0: number, x1: number, y: number, h: number}}
   */
  bar(k) {
    const fx = this.effects.effects[k];
    const rows = this._rows;
    const h = this.canvas.clientHeight / rows;
    return { x0: this._x(fx.start_s), x1: this._x(fx.end_s), y: (k % rows) * h, h };
  }

  /** The bar end under (x, y) (the nearest within GRAB_PX), or the bar under it, or null.
   * @param {number} x @param {number} y
   * @returns {{k: number, end: "start_s"|"end_s"|null}|null} */
  _hit(x, y) {
    let best = null;
    let bestD = GRAB_PX;
    let body = null;
    this.effects.effects.forEach((_, k) => {
      const b = this.bar(k);
      if (y < b.y || y > b.y + b.h) return;
      for (const end of /** @type {const} */ (["start_s", "end_s"])) {
        const d = Math.abs((end === "start_s" ? b.x0 : b.x1) - x);
        if (d <= bestD) { bestD = d; best = { k, end }; }
      }
      if (x >= b.x0 && x <= b.x1) body = { k, end: null };
    });
    return best || body;
  }

  /** @param {PointerEvent} e */
  _down(e) {
    const h = this._hit(e.offsetX, e.offsetY);
    if (!h) return;
    this.effects.selected = h.k;
    this.effects.render();
    if (h.end) {
      this._drag = { k: h.k, end: h.end, t: this.effects.effects[h.k][h.end] };
      this.canvas.setPointerCapture(e.pointerId);
    }
    this.draw();
  }

  /** @param {PointerEvent} e */
  _move(e) {
    const d = this._drag;
    if (!d) {
      const h = this._hit(e.offsetX, e.offsetY);
      this.canvas.style.cursor = h ? (h.end ? "ew-resize" : "pointer") : "default";
      return;
    }
    const fx = this.effects.effects[d.k];
    let t = snapTime(Math.max(0, this._t(e.offsetX)), this.music.snapPoints(), e.shiftKey ? 0 : this._t(SNAP_PX));
    // An end never crosses the other one.
    t = d.end === "start_s" ? Math.min(t, fx.end_s - MIN_LENGTH_S) : Math.max(t, fx.start_s + MIN_LENGTH_S);
    d.t = Math.max(0, t);
    d.moved = true;
    this.draw();
  }

  /** @param {PointerEvent} e */
  _up(e) {
    const d = this._drag;
    this._drag = null;
    if (this.canvas.hasPointerCapture(e.pointerId)) this.canvas.releasePointerCapture(e.pointerId);
    if (!d || !d.moved) { this.draw(); return; }
    const t = +d.t.toFixed(3);
    this.effects.change(d.k, d.end === "start_s" ? "Effect start" : "Effect end", (c) => {
      c[d.end] = t;
      // Fades longer than the effect would be refused: shorten them with it.
      const len = c.end_s - c.start_s;
      c.fade_in_s = Math.min(c.fade_in_s || 0, len);
      c.fade_out_s = Math.min(c.fade_out_s || 0, len - c.fade_in_s);
    });
    this.draw();
  }

  /** Redraw the bars and the playhead. */
  draw() {
    const c = this.canvas;
    const fit = fitCanvas(c);
    if (!fit) return;
    const { g, w, h } = fit;
    const list = this.effects.effects;
    g.font = "10px sans-serif";
    list.forEach((fx, k) => {
      const b = this.bar(k);
      const d = this._drag && this._drag.k === k ? this._drag : null;
      const x0 = d && d.end === "start_s" ? this._x(d.t) : b.x0;
      const x1 = d && d.end === "end_s" ? this._x(d.t) : b.x1;
      const selected = k === this.effects.selected;
      const e = fx.effect || {};
      const color = e.color || (Array.isArray(e.colors) ? e.colors[0] : "#9aa7b8");
      g.globalAlpha = fx.enabled === false ? 0.3 : 0.75;
      g.fillStyle = color;
      g.fillRect(x0, b.y + 1, Math.max(1, x1 - x0), b.h - 2);
      g.globalAlpha = 1;
      g.strokeStyle = selected ? "#ff9f43" : "#e0e0e0";
      g.lineWidth = selected ? 2 : 1;
      g.strokeRect(x0, b.y + 1, Math.max(1, x1 - x0), b.h - 2);
      g.fillStyle = "#10151d";
      g.fillRect(x0, b.y + 1, 3, b.h - 2);
      g.fillRect(x1 - 3, b.y + 1, 3, b.h - 2);
      if (b.h >= 10) {
        g.fillStyle = "#ffffff";
        g.fillText((fx.name || e.kind || "").slice(0, 20), x0 + 5, b.y + b.h / 2 + 3.5);
      }
    });
    g.fillStyle = "#ff4757";
    g.fillRect(this._x(this.music.time_s) - 1, 0, 2, h);
    c.setAttribute("aria-label", `Effect lane: ${list.length} effect${list.length === 1 ? "" : "s"}; drag a bar's end to move it (snaps to beats)`);
  }
}
