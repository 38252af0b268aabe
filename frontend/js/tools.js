// @ts-check
// Canvas editing tools: select (click, box, move), freehand draw (resampled to the drone count),
// place, erase, pan. Every finished gesture is one undo step. In the free 3D view a move drags the
// selection in the plane through it facing the camera, or along one axis (`moveAxis`); the pan
// tool orbits there.

import { axisParameter } from "./camera.js";
import { resamplePolylines, roundPoints } from "./geometry.js";
import { closePairs, roundKeepingSpacing } from "./spacing.js";

/** Tool names, in the order of the tool buttons. */
export const TOOLS = ["select", "draw", "place", "erase", "pan"];

/** Constraints of a move: free (the view's plane, or the camera-facing plane in 3D), or one axis. */
export const MOVE_AXES = ["free", "x", "y", "z"];

/** Pointer gestures on the canvas, turned into edits of the current formation. */
export class Tools {
  /**
   * @param {import("./canvas.js").CanvasView} view
   * @param {import("./state.js").EditorState} state
   * @param {{color: () => string, onError: (msg: string) => void}} opts
   */
  constructor(view, state, opts) {
    this.view = view;
    this.state = state;
    this.opts = opts;
    this.tool = "select";
    /** @type {"free"|"x"|"y"|"z"} what a drag moves along */
    this.moveAxis = "free";
    this._gesture = null;
    /** Strokes of the current drawing (world u, v), so Shift+draw can add one more stroke. */
    this.strokes = [];
    this._strokesFor = -1;
    const c = view.canvas;
    c.addEventListener("pointerdown", (e) => this._down(e));
    c.addEventListener("pointermove", (e) => this._move(e));
    c.addEventListener("pointerup", (e) => this._up(e));
    c.addEventListener("pointercancel", () => this.cancel());
    state.addEventListener("change", (/** @type {any} */ e) => {
      if (e.detail.kind === "current" || e.detail.kind === "load") this.strokes = [];
    });
  }

  /**
   * Choose the active tool.
   * @param {string} tool one of {@link TOOLS}
   */
  setTool(tool) {
    if (!TOOLS.includes(tool)) return;
    this.cancel();
    this.tool = tool;
    const c = this.view.canvas;
    for (const t of TOOLS) c.classList.toggle(`tool-${t}`, t === tool);
  }

  /** Abandon the gesture in progress (Escape): a half-done move is undone. */
  cancel() {
    const g = this._gesture;
    this._gesture = null;
    if (g && g.kind === "move" && g.moved) this.state.rollback();
    this.view.overlay = { strokes: [], box: null };
    this.view.redraw();
  }

  _down(e) {
    if (e.button !== 0 || this.view.panning || !this.state.formation) return;
    const c = this.view.canvas;
    c.focus();
    const sx = e.offsetX;
    const sy = e.offsetY;
    const uv = this.view.toWorldUV(sx, sy);
    if (this.tool === "pan") {
      this.view.startPan(e);
      return;
    }
    if (this.view.is3d && (this.tool === "draw" || this.tool === "place")) {
      this.opts.onError("Draw and Place work in the front, top and side views (the 3D view has no drawing plane).");
      return;
    }
    c.setPointerCapture(e.pointerId);
    if (this.tool === "select") {
      const hit = this.view.hitTest(sx, sy);
      if (hit >= 0) {
        const sel = new Set(this.state.selection);
        if (e.shiftKey || e.ctrlKey || e.metaKey) {
          if (sel.has(hit)) sel.delete(hit);
          else sel.add(hit);
          this.state.setSelection(sel);
          if (!sel.has(hit)) return;
        } else if (!sel.has(hit)) {
          this.state.setSelection([hit]);
        }
        this.state.checkpoint();
        const f = this.state.formation;
        const idx = [...this.state.selection];
        const orig = idx.map((i) => f.points[i].slice());
        this._gesture = { kind: "move", start: uv, sx, sy, idx, orig, moved: false, anchor: f.points[hit].slice() };
        if (this.view.is3d) this._gesture.start3d = this._dragPoint(sx, sy, this._gesture.anchor);
      } else {
        this._gesture = { kind: "box", x0: sx, y0: sy, add: e.shiftKey || e.ctrlKey || e.metaKey };
      }
    } else if (this.tool === "draw") {
      if (this._strokesFor !== this.state.current || !e.shiftKey) this.strokes = [];
      this._strokesFor = this.state.current;
      this._gesture = { kind: "draw", stroke: [uv], sx, sy };
      this.view.overlay = { strokes: [...this.strokes, this._gesture.stroke], box: null };
    } else if (this.tool === "place") {
      const p = roundPoints([this.view.pointAt(uv[0], uv[1])])[0];
      const color = this.opts.color();
      this.state.edit("Add point", () => {
        const f = this.state.formation;
        f.points.push(p);
        f.colors.push(color);
        this.state.selection = new Set([f.points.length - 1]);
      });
    } else if (this.tool === "erase") {
      this.state.checkpoint();
      this._gesture = { kind: "erase", removed: 0 };
      this._eraseAt(sx, sy);
    }
    this.view.redraw();
  }

  _move(e) {
    const g = this._gesture;
    if (!g) return;
    const sx = e.offsetX;
    const sy = e.offsetY;
    if (g.kind === "move") {
      if (!g.moved && Math.hypot(sx - g.sx, sy - g.sy) < 3) return;
      const delta = this._moveDelta(g, sx, sy);
      if (!delta) return;
      g.moved = true;
      const f = this.state.formation;
      g.idx.forEach((i, k) => {
        for (let c = 0; c < 3; c++) f.points[i][c] = g.orig[k][c] + delta[c];
      });
      this.state.touch();
    } else if (g.kind === "box") {
      this.view.overlay = { strokes: [], box: { x0: g.x0, y0: g.y0, x1: sx, y1: sy } };
    } else if (g.kind === "draw") {
      const last = g.stroke[g.stroke.length - 1];
      const uv = this.view.toWorldUV(sx, sy);
      if (Math.hypot(uv[0] - last[0], uv[1] - last[1]) * this.view.scale >= 2) {
        g.stroke.push(uv);
        this.view.overlay.preview = this._preview(g.stroke);
      }
    } else if (g.kind === "erase") {
      this._eraseAt(sx, sy);
    }
    this.view.redraw();
  }

  _up(e) {
    const g = this._gesture;
    this._gesture = null;
    const c = this.view.canvas;
    if (c.hasPointerCapture(e.pointerId)) c.releasePointerCapture(e.pointerId);
    if (!g) return;
    if (g.kind === "move") {
      const f = this.state.formation;
      if (g.moved) f.points = roundKeepingSpacing(f.points, this.state.show.settings.min_distance_m, g.idx);
      // A drag along an axis pointing into the screen (or back to the start) changes nothing: no undo step.
      if (g.moved && g.idx.some((i, k) => f.points[i].some((v, c) => v !== g.orig[k][c]))) {
        this.state.commit(g.idx.length === 1 ? "Move point" : `Move ${g.idx.length} points`);
      } else {
        this.state.discard();
      }
    } else if (g.kind === "box") {
      const moved = Math.hypot(e.offsetX - g.x0, e.offsetY - g.y0) >= 3;
      const inside = moved ? this.view.pointsInRect(g.x0, g.y0, e.offsetX, e.offsetY) : [];
      const sel = g.add ? new Set([...this.state.selection, ...inside]) : new Set(inside);
      this.state.setSelection(sel);
    } else if (g.kind === "draw") {
      this._finishStroke(g);
    } else if (g.kind === "erase") {
      if (g.removed) this.state.commit(`Delete ${g.removed} point${g.removed > 1 ? "s" : ""}`);
      else this.state.discard();
    }
    this.view.overlay = { strokes: [], box: null };
    this.view.redraw();
  }

  /**
   * Where a 3D drag holds the grabbed point: on the plane through `anchor` facing the camera, or
   * the axis parameter when the move is along one axis.
   * @param {number} sx @param {number} sy @param {number[]} anchor
   * @returns {number[]|number|null}
   */
  _dragPoint(sx, sy, anchor) {
    const cam = this.view.camera;
    if (this.moveAxis === "free") return cam.unprojectAt(sx, sy, anchor);
    const a = [0, 0, 0];
    a[MOVE_AXES.indexOf(this.moveAxis) - 1] = 1;
    return axisParameter(cam.ray(sx, sy), anchor, a);
  }

  /**
   * The displacement (metres, x y z) of a move gesture with the pointer at (sx, sy), or null
   * where the pointer does not meet the drag plane or axis.
   * @returns {number[]|null}
   */
  _moveDelta(g, sx, sy) {
    const axis = MOVE_AXES.indexOf(this.moveAxis) - 1; // -1: free
    if (this.view.is3d) {
      const now = this._dragPoint(sx, sy, g.anchor);
      if (now === null || g.start3d === null || g.start3d === undefined) return null;
      if (typeof now === "number") {
        const d = [0, 0, 0];
        d[axis] = now - /** @type {number} */ (g.start3d);
        return d;
      }
      const s = /** @type {number[]} */ (g.start3d);
      return [now[0] - s[0], now[1] - s[1], now[2] - s[2]];
    }
    const uv = this.view.toWorldUV(sx, sy);
    const [a, b] = this.view.axes;
    const d = [0, 0, 0];
    d[a] = uv[0] - g.start[0];
    d[b] = uv[1] - g.start[1];
    // Along one axis: keep that component only (an axis into the screen does not move).
    if (axis >= 0) for (let c = 0; c < 3; c++) if (c !== axis) d[c] = 0;
    return d;
  }

  _eraseAt(sx, sy) {
    const i = this.view.hitTest(sx, sy, 9);
    if (i < 0) return;
    const f = this.state.formation;
    f.points.splice(i, 1);
    f.colors.splice(i, 1);
    this.state.selection = new Set();
    this._gesture.removed += 1;
    this.state.touch();
  }

  /** Where the drones would go if the stroke ended here, with the too-close ones flagged. */
  _preview(stroke) {
    const n = this.state.show.drones;
    if (n > 5000) return null;
    const uv = resamplePolylines(this._closedStrokes([...this.strokes, stroke]), n, 1e-9);
    const { close } = closePairs(uv.map(([u, v]) => [u, v, 0]), this.state.show.settings.min_distance_m);
    return { uv, close };
  }

  _closedStrokes(list) {
    const closeTol = Math.max(this.state.show.settings.min_distance_m, 12 / this.view.scale);
    // A stroke whose end comes back near its start is closed: snap the end onto the start.
    return list.map((s) => {
      const a = s[0];
      const b = s[s.length - 1];
      return s.length > 3 && Math.hypot(a[0] - b[0], a[1] - b[1]) <= closeTol ? [...s, a] : s;
    });
  }

  _finishStroke(g) {
    const stroke = g.stroke;
    let len = 0;
    for (let i = 1; i < stroke.length; i++) len += Math.hypot(stroke[i][0] - stroke[i - 1][0], stroke[i][1] - stroke[i - 1][1]);
    if (len * this.view.scale < 6) return; // a click, not a stroke
    this.strokes.push(stroke);
    const n = this.state.show.drones;
    const uv = resamplePolylines(this._closedStrokes(this.strokes), n, 1e-9);
    const pts = roundPoints(uv.map(([u, v]) => this.view.pointAt(u, v)));
    const color = this.opts.color();
    const total = this.strokes.length;
    this.state.edit(total > 1 ? `Draw stroke ${total}` : "Draw stroke", () => {
      const f = this.state.formation;
      f.points = pts;
      f.colors = pts.map(() => color);
      this.state.selection = new Set();
    });
  }
}
