// @ts-check
// The formation canvas: front (x-z), top (x-y) or side (y-z) view of the current formation, a
// metre grid, zoom about the cursor, pan, hit testing; or a free 3D view through an orbit camera
// (camera.js) with the same hit testing on the projected points. Editing gestures live in tools.js.

import { OrbitCamera } from "./camera.js";
import { AXIS_NAMES, VIEW_AXES } from "./geometry.js";
import { homePositions } from "./launch.js";
import { formationColors } from "./state.js";

const NICE_STEPS = [0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000];

/** Draws the current formation and maps between screen pixels and metres. */
export class CanvasView {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {import("./state.js").EditorState} state
   */
  constructor(canvas, state) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.state = state;
    /** @type {"front"|"top"|"side"|"3d"} */
    this.view = "front";
    /** The free 3D view's camera. */
    this.camera = new OrbitCamera();
    this.scale = 6; // pixels per metre
    this.center = [0, 40]; // metres at the canvas centre (u, v)
    this.depth = 0; // metres along the hidden axis for new points
    /** @type {Set<number>} indices closer than the minimum distance */
    this.close = new Set();
    /** @type {Set<number>} points flagged by a check violation */
    this.flagged = new Set();
    /** @type {((f: any) => any)|null} draws a formation moved (motion.js plays a hold's motion) */
    this.moved = null;
    /** @type {((f: any, base: string[]) => (string[]|null))|null} colours painted over the formation's (effects preview) */
    this.colorOverride = null;
    /** Transient drawing from tools: a stroke being drawn, a selection box. */
    this.overlay = { strokes: [], box: null };
    this.onCursor = null;
    this._queued = false;
    this._pan = null;
    this._spaceDown = false;

    new ResizeObserver(() => this._resize()).observe(canvas);
    canvas.addEventListener("wheel", (e) => this._wheel(e), { passive: false });
    canvas.addEventListener("pointerdown", (e) => this._maybePan(e), true);
    canvas.addEventListener("pointermove", (e) => {
      if (this._pan) this._panMove(e);
      if (this.onCursor) this.onCursor(this.toWorldUV(e.offsetX, e.offsetY));
    });
    canvas.addEventListener("pointerup", (e) => this._panEnd(e), true);
    window.addEventListener("keydown", (e) => {
      if (e.code === "Space" && document.activeElement === canvas) { this._spaceDown = true; e.preventDefault(); }
    });
    window.addEventListener("keyup", (e) => { if (e.code === "Space") this._spaceDown = false; });
    this._resize();
  }

  /** @returns {[number, number, number]} [horizontal, vertical, depth] axis indices of the view. */
  get axes() {
    return /** @type {[number, number, number]} */ (VIEW_AXES[this.view]);
  }

  /** @returns {boolean} the free 3D view is shown. */
  get is3d() {
    return this.view === "3d";
  }

  /**
   * Switch between the front, top, side and 3D views.
   * @param {"front"|"top"|"side"|"3d"} view
   */
  setView(view) {
    if (!VIEW_AXES[view] || view === this.view) return;
    this.view = view;
    this.fit();
  }

  _resize() {
    const dpr = window.devicePixelRatio || 1;
    const r = this.canvas.getBoundingClientRect();
    this.width = Math.max(1, r.width);
    this.height = Math.max(1, r.height);
    this.canvas.width = Math.round(this.width * dpr);
    this.canvas.height = Math.round(this.height * dpr);
    this.ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    this.camera.width = this.width;
    this.camera.height = this.height;
    this.redraw();
  }

  /**
   * Screen pixel (CSS px from the canvas' top left) -> view coordinates in metres.
   * @param {number} sx @param {number} sy
   * @returns {[number, number]}
   */
  toWorldUV(sx, sy) {
    return [this.center[0] + (sx - this.width / 2) / this.scale, this.center[1] - (sy - this.height / 2) / this.scale];
  }

  /**
   * View coordinates (metres) -> screen pixels.
   * @param {number} u @param {number} v
   * @returns {[number, number]}
   */
  toScreen(u, v) {
    return [this.width / 2 + (u - this.center[0]) * this.scale, this.height / 2 - (v - this.center[1]) * this.scale];
  }

  /**
   * Screen positions of points in the current view: flat [x0, y0, x1, y1, ...] pixels, and in the
   * 3D view the depth of each (metres along the view direction; <= 0 is behind the camera).
   * @param {number[][]} points
   * @returns {{xy: Float64Array, depth: Float64Array|null}}
   */
  project(points) {
    const xy = new Float64Array(points.length * 2);
    if (this.is3d) {
      // camera.project, inlined: no arrays allocated per point (5,000 points per frame).
      const { eye: e, forward: f, right: r, up: u, focal } = this.camera.frame();
      const w2 = this.width / 2;
      const h2 = this.height / 2;
      const depth = new Float64Array(points.length);
      for (let i = 0; i < points.length; i++) {
        const p = points[i];
        const dx = p[0] - e[0];
        const dy = p[1] - e[1];
        const dz = p[2] - e[2];
        const z = dx * f[0] + dy * f[1] + dz * f[2];
        const k = focal / z;
        xy[2 * i] = w2 + (dx * r[0] + dy * r[1] + dz * r[2]) * k;
        xy[2 * i + 1] = h2 - (dx * u[0] + dy * u[1] + dz * u[2]) * k;
        depth[i] = z;
      }
      return { xy, depth };
    }
    const [a, b] = this.axes;
    const w2 = this.width / 2 - this.center[0] * this.scale;
    const h2 = this.height / 2 + this.center[1] * this.scale;
    for (let i = 0; i < points.length; i++) {
      xy[2 * i] = w2 + points[i][a] * this.scale;
      xy[2 * i + 1] = h2 - points[i][b] * this.scale;
    }
    return { xy, depth: null };
  }

  /**
   * A 3-D point for view coordinates, at the canvas depth.
   * @param {number} u @param {number} v
   * @returns {number[]}
   */
  pointAt(u, v) {
    const [a, b, d] = this.axes;
    const p = [0, 0, 0];
    p[a] = u;
    p[b] = v;
    p[d] = this.depth;
    return p;
  }

  /**
   * Zoom by a factor keeping the world point under (sx, sy) fixed.
   * @param {number} factor @param {number} [sx] @param {number} [sy]
   */
  zoom(factor, sx = this.width / 2, sy = this.height / 2) {
    if (this.is3d) {
      this.camera.distance_m = Math.min(20000, Math.max(1, this.camera.distance_m / factor));
      this.redraw();
      return;
    }
    const [u, v] = this.toWorldUV(sx, sy);
    this.scale = Math.min(400, Math.max(0.05, this.scale * factor));
    this.center = [u - (sx - this.width / 2) / this.scale, v + (sy - this.height / 2) / this.scale];
    this.redraw();
  }

  /** Zoom and pan so the current formation (and the ground) fill the canvas. */
  fit() {
    const f = this.state.formation;
    if (this.is3d) {
      this._fit3d(f ? f.points : []);
      return;
    }
    const [a, b] = this.axes;
    let lo = [Infinity, Infinity];
    let hi = [-Infinity, -Infinity];
    for (const p of f ? f.points : []) {
      lo = [Math.min(lo[0], p[a]), Math.min(lo[1], p[b])];
      hi = [Math.max(hi[0], p[a]), Math.max(hi[1], p[b])];
    }
    if (!Number.isFinite(lo[0])) { lo = [-30, 0]; hi = [30, 60]; }
    if (this.view === "front") lo[1] = Math.min(lo[1], 0);
    const w = Math.max(hi[0] - lo[0], 10);
    const h = Math.max(hi[1] - lo[1], 10);
    this.scale = Math.max(0.05, Math.min((this.width * 0.85) / w, (this.height * 0.85) / h));
    this.center = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2];
    this.redraw();
  }

  /** Aim the orbit camera at the points' bounding box and back off until its sphere fits. */
  _fit3d(points) {
    const lo = [Infinity, Infinity, Infinity];
    const hi = [-Infinity, -Infinity, -Infinity];
    for (const p of points) for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]); }
    const cam = this.camera;
    if (!Number.isFinite(lo[0])) { cam.target = [0, 0, 30]; cam.distance_m = 150; this.redraw(); return; }
    cam.target = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
    const radius = Math.max(5, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
    const half = Math.min(cam.fov_rad, 2 * Math.atan(Math.tan(cam.fov_rad / 2) * (this.width / this.height))) / 2;
    cam.distance_m = (radius / Math.sin(half)) * 1.05;
    this.redraw();
  }

  _wheel(e) {
    e.preventDefault();
    const factor = Math.exp(-e.deltaY * (e.deltaMode === 1 ? 0.05 : 0.0015));
    this.zoom(factor, e.offsetX, e.offsetY);
  }

  /**
   * Start panning from a pointer event (used by the pan tool too).
   * @param {PointerEvent} e
   */
  startPan(e) {
    // In 3D a drag orbits the camera about its target; with Shift it moves the target.
    const cam = this.camera;
    this._pan = {
      x: e.offsetX, y: e.offsetY, center: this.center.slice(), id: e.pointerId,
      orbit: this.is3d && !e.shiftKey, yaw: cam.yaw_rad, pitch: cam.pitch_rad, target: cam.target.slice(),
    };
    this.canvas.setPointerCapture(e.pointerId);
    this.canvas.classList.add("panning");
  }

  _maybePan(e) {
    if (e.button === 1 || (e.button === 0 && this._spaceDown)) {
      e.stopImmediatePropagation();
      e.preventDefault();
      this.startPan(e);
    }
  }

  _panMove(e) {
    const p = this._pan;
    if (this.is3d) {
      const cam = this.camera;
      const dx = e.offsetX - p.x;
      const dy = e.offsetY - p.y;
      if (p.orbit) {
        cam.yaw_rad = p.yaw - dx * 0.008;
        cam.pitch_rad = Math.max(-1.5, Math.min(1.5, p.pitch + dy * 0.008));
      } else {
        const fr = cam.frame();
        const m = cam.distance_m / fr.focal; // metres per pixel at the target
        cam.target = /** @type {[number, number, number]} */ (p.target.map((t, k) => t - dx * m * fr.right[k] + dy * m * fr.up[k]));
      }
      this.redraw();
      return;
    }
    this.center = [p.center[0] - (e.offsetX - p.x) / this.scale, p.center[1] + (e.offsetY - p.y) / this.scale];
    this.redraw();
  }

  _panEnd(e) {
    if (!this._pan) return;
    this._pan = null;
    this.canvas.classList.remove("panning");
    if (this.canvas.hasPointerCapture(e.pointerId)) this.canvas.releasePointerCapture(e.pointerId);
    e.stopImmediatePropagation();
  }

  /** @returns {boolean} a pan gesture is in progress. */
  get panning() {
    return this._pan !== null;
  }

  /**
   * Index of the point nearest to a screen position within `radius` pixels, or -1.
   * @param {number} sx @param {number} sy @param {number} [radius]
   */
  hitTest(sx, sy, radius = 8) {
    const f = this.state.formation;
    if (!f) return -1;
    const { xy, depth } = this.project(f.points);
    let best = -1;
    let bd = radius * radius;
    let bz = Infinity;
    for (let i = 0; i < f.points.length; i++) {
      if (depth && depth[i] <= 0) continue;
      const d = (xy[2 * i] - sx) ** 2 + (xy[2 * i + 1] - sy) ** 2;
      // In 3D, of the points under the cursor the nearest to the camera wins (it is drawn on top).
      if (depth ? d <= radius * radius && (depth[i] < bz - 1e-9 || (Math.abs(depth[i] - bz) <= 1e-9 && d < bd)) : d <= bd) {
        bd = d;
        best = i;
        if (depth) bz = depth[i];
      }
    }
    return best;
  }

  /**
   * Indices of the points inside a screen rectangle.
   * @param {number} x0 @param {number} y0 @param {number} x1 @param {number} y1
   * @returns {number[]}
   */
  pointsInRect(x0, y0, x1, y1) {
    const f = this.state.formation;
    if (!f) return [];
    const { xy, depth } = this.project(f.points);
    const [lx, hx] = [Math.min(x0, x1), Math.max(x0, x1)];
    const [ly, hy] = [Math.min(y0, y1), Math.max(y0, y1)];
    const out = [];
    for (let i = 0; i < f.points.length; i++) {
      if (depth && depth[i] <= 0) continue;
      const x = xy[2 * i];
      const y = xy[2 * i + 1];
      if (x >= lx && x <= hx && y >= ly && y <= hy) out.push(i);
    }
    return out;
  }

  /** Redraw on the next animation frame. */
  redraw() {
    if (this._queued) return;
    this._queued = true;
    requestAnimationFrame(() => {
      this._queued = false;
      this._draw();
    });
  }

  _gridStep() {
    const target = 60 / this.scale; // about 60 px between lines
    return NICE_STEPS.find((s) => s >= target) ?? NICE_STEPS[NICE_STEPS.length - 1];
  }

  _draw() {
    const { ctx, width: w, height: h } = this;
    ctx.clearRect(0, 0, w, h);
    ctx.fillStyle = "#0a0f1a";
    ctx.fillRect(0, 0, w, h);
    if (this.is3d) this._drawGround3d();
    else this._drawGrid();
    const show = this.state.show;
    if (!show) return;
    if (this.is3d) this._drawLimits3d(show);
    else this._drawLimits(show);
    this._drawHome(show);
    const prev = show.formations[this.state.current - 1];
    if (prev) this._drawPoints(prev, { ghost: true });
    const f = this.state.formation;
    // A formation's motion during its hold (motion.js) plays by drawing it moved.
    if (f) this._drawPoints(this.moved ? this.moved(f) : f, { ghost: false });
    this._drawOverlay();
  }

  _drawGrid() {
    const { ctx, width: w, height: h } = this;
    const step = this._gridStep();
    const [u0, v1] = this.toWorldUV(0, 0);
    const [u1, v0] = this.toWorldUV(w, h);
    ctx.lineWidth = 1;
    ctx.font = "10px system-ui, sans-serif";
    ctx.fillStyle = "#5d6b8c";
    for (let u = Math.ceil(u0 / step) * step; u <= u1; u += step) {
      const [x] = this.toScreen(u, 0);
      ctx.strokeStyle = Math.abs(u) < 1e-9 ? "#3b4a73" : "#182036";
      ctx.beginPath();
      ctx.moveTo(Math.round(x) + 0.5, 0);
      ctx.lineTo(Math.round(x) + 0.5, h);
      ctx.stroke();
      ctx.fillText(`${+u.toFixed(2)} m`, x + 3, h - 4);
    }
    for (let v = Math.ceil(v0 / step) * step; v <= v1; v += step) {
      const [, y] = this.toScreen(0, v);
      ctx.strokeStyle = Math.abs(v) < 1e-9 ? "#3b4a73" : "#182036";
      ctx.beginPath();
      ctx.moveTo(0, Math.round(y) + 0.5);
      ctx.lineTo(w, Math.round(y) + 0.5);
      ctx.stroke();
      ctx.fillText(`${+v.toFixed(2)} m`, 3, y - 3);
    }
    const names = [AXIS_NAMES[this.axes[0]], AXIS_NAMES[this.axes[1]]];
    ctx.fillStyle = "#8d99b5";
    ctx.fillText(`${names[0]} →   ${names[1]} ↑   grid ${step} m`, w - 230, 14);
  }

  /** The 3D view's ground: a metre grid on z = 0 around the target, and the x, y, z axes. */
  _drawGround3d() {
    const { ctx, camera: cam } = this;
    const fr = cam.frame();
    const step = NICE_STEPS.find((s) => s >= cam.distance_m / 12) ?? 1000;
    const n = 12;
    const cx = Math.round(cam.target[0] / step) * step;
    const cy = Math.round(cam.target[1] / step) * step;
    const seg = (p, q) => this._segment3d(p, q, fr);
    ctx.lineWidth = 1;
    ctx.strokeStyle = "#182036";
    for (let k = -n; k <= n; k++) {
      seg([cx + k * step, cy - n * step, 0], [cx + k * step, cy + n * step, 0]);
      seg([cx - n * step, cy + k * step, 0], [cx + n * step, cy + k * step, 0]);
    }
    const len = step * 3;
    const axes = [["x", "#d0543c"], ["y", "#3fae5a"], ["z", "#4a7bd0"]];
    axes.forEach(([name, color], k) => {
      const end = [0, 0, 0];
      end[k] = len;
      ctx.strokeStyle = color;
      ctx.lineWidth = 2;
      seg([0, 0, 0], end);
      const [x, y, z] = cam.project(end, fr);
      if (z > 0) { ctx.fillStyle = color; ctx.fillText(name, x + 3, y - 3); }
    });
    ctx.lineWidth = 1;
    ctx.font = "10px system-ui, sans-serif";
    ctx.fillStyle = "#8d99b5";
    ctx.fillText(`3D: drag with Pan (H) or middle button to orbit, Shift to pan · grid ${step} m`, 8, 14);
  }

  /** A world segment in the 3D view, clipped to in front of the camera (stroked as the context is set). */
  _segment3d(p, q, fr) {
    const { ctx, camera: cam } = this;
    let a = cam.project(p, fr);
    let b = cam.project(q, fr);
    const near = 0.5;
    if (a[2] < near && b[2] < near) return;
    if (a[2] < near || b[2] < near) {
      const t = (near - a[2]) / (b[2] - a[2]);
      const c = cam.project(p.map((v, k) => v + t * (q[k] - v)), fr);
      if (a[2] < near) a = c;
      else b = c;
    }
    ctx.beginPath();
    ctx.moveTo(a[0], a[1]);
    ctx.lineTo(b[0], b[1]);
    ctx.stroke();
  }

  /** The 3D view's limits: the geofence as a box from the ground to the maximum altitude. */
  _drawLimits3d(show) {
    /** @type {string[]} */
    this.drawnLimits = [];
    const g = show.settings.geofence;
    if (!g) return;
    const fr = this.camera.frame();
    const { ctx } = this;
    const top = show.settings.max_altitude_m;
    const corners = [[g.x_min_m, g.y_min_m], [g.x_max_m, g.y_min_m], [g.x_max_m, g.y_max_m], [g.x_min_m, g.y_max_m]];
    ctx.save();
    ctx.setLineDash([8, 4]);
    corners.forEach(([x, y], k) => {
      const [x2, y2] = corners[(k + 1) % 4];
      // The audience edge (y = y_min) in the fence's colour, the others fainter.
      ctx.strokeStyle = k === 0 ? "#d0543c" : "rgba(208, 84, 60, 0.45)";
      this._segment3d([x, y, 0], [x2, y2, 0], fr);
      this._segment3d([x, y, top], [x2, y2, top], fr);
      ctx.strokeStyle = "rgba(208, 84, 60, 0.3)";
      this._segment3d([x, y, 0], [x, y, top], fr);
    });
    ctx.restore();
    this.drawnLimits.push(`geofence x ${g.x_min_m}..${g.x_max_m} m, y ${g.y_min_m}..${g.y_max_m} m, up to ${top} m`);
  }

  _drawLimits(show) {
    /** @type {string[]} what the limits drawing shows (for tests and the status) */
    this.drawnLimits = [];
    this._drawFence(show);
    if (this.view !== "front" && this.view !== "side") return;
    const { ctx, width: w } = this;
    const [, yg] = this.toScreen(0, 0);
    ctx.fillStyle = "rgba(60, 90, 60, 0.18)";
    ctx.fillRect(0, yg, w, this.height - yg);
    ctx.strokeStyle = "#3f6d4a";
    ctx.beginPath();
    ctx.moveTo(0, yg);
    ctx.lineTo(w, yg);
    ctx.stroke();
    const [, ya] = this.toScreen(0, show.settings.max_altitude_m);
    ctx.setLineDash([6, 4]);
    ctx.strokeStyle = "#7a3b48";
    ctx.beginPath();
    ctx.moveTo(0, ya);
    ctx.lineTo(w, ya);
    ctx.stroke();
    ctx.setLineDash([]);
    ctx.fillStyle = "#b86b78";
    ctx.fillText(`max altitude ${show.settings.max_altitude_m} m`, 40, ya - 4);
    // The altitude floor (outside takeoff and landing), checked exactly by "Check".
    const floor = show.settings.min_altitude_m ?? 2.5;
    const [, yf] = this.toScreen(0, floor);
    ctx.setLineDash([3, 5]);
    ctx.strokeStyle = "#b8893b";
    ctx.beginPath();
    ctx.moveTo(0, yf);
    ctx.lineTo(w, yf);
    ctx.stroke();
    ctx.setLineDash([]);
    ctx.fillStyle = "#c9a35d";
    ctx.fillText(`min altitude ${floor} m`, 40, yf - 4);
    this.drawnLimits.push(`min altitude ${floor} m`);
  }

  /** The geofence: its x edges in the front view, its y edges in the side view, the whole box (audience side shaded) from the top. */
  _drawFence(show) {
    const g = show.settings.geofence;
    if (!g) return;
    const { ctx, width: w, height: h } = this;
    ctx.save();
    ctx.strokeStyle = "#d0543c";
    ctx.fillStyle = "rgba(208, 84, 60, 0.10)";
    ctx.setLineDash([8, 4]);
    const [x0] = this.toScreen(g.x_min_m, 0);
    const [x1] = this.toScreen(g.x_max_m, 0);
    if (this.view === "side") {
      const [ya] = this.toScreen(g.y_min_m, 0);
      const [yb] = this.toScreen(g.y_max_m, 0);
      ctx.fillRect(0, 0, Math.max(0, ya), h); // the audience side, in front of the fence (left)
      ctx.beginPath();
      ctx.moveTo(ya, 0); ctx.lineTo(ya, h);
      ctx.moveTo(yb, 0); ctx.lineTo(yb, h);
      ctx.stroke();
      ctx.fillStyle = "#e07a66";
      ctx.fillText("audience side", Math.max(4, ya - 90), 40);
    } else if (this.view === "front") {
      ctx.fillRect(0, 0, Math.max(0, x0), h);
      ctx.fillRect(x1, 0, Math.max(0, w - x1), h);
      ctx.beginPath();
      ctx.moveTo(x0, 0); ctx.lineTo(x0, h);
      ctx.moveTo(x1, 0); ctx.lineTo(x1, h);
      ctx.stroke();
    } else {
      const [, y0] = this.toScreen(0, g.y_min_m);
      const [, y1] = this.toScreen(0, g.y_max_m);
      ctx.fillRect(0, y0, w, Math.max(0, h - y0)); // the audience side, in front of the fence
      ctx.strokeRect(x0, y1, x1 - x0, y0 - y1);
      ctx.fillStyle = "#e07a66";
      ctx.fillText("audience side", x0 + 4, y0 + 12);
    }
    ctx.setLineDash([]);
    ctx.fillStyle = "#e07a66";
    ctx.fillText("geofence", x0 + 4, 26);
    ctx.restore();
    this.drawnLimits.push(`geofence x ${g.x_min_m}..${g.x_max_m} m, y ${g.y_min_m}..${g.y_max_m} m`);
  }

  _drawHome(show) {
    const pts = homePositions(show).points.slice(0, show.drones);
    const { xy, depth } = this.project(pts);
    this.ctx.fillStyle = "#3a4a6b";
    for (let i = 0; i < pts.length; i++) {
      if (depth && depth[i] <= 0) continue;
      this.ctx.fillRect(xy[2 * i] - 1.5, xy[2 * i + 1] - 1.5, 3, 3);
    }
  }

  _drawPoints(f, { ghost }) {
    const { ctx } = this;
    const spacing = this.state.show.settings.min_distance_m;
    const r2d = Math.max(2, Math.min(7, spacing * this.scale * 0.22));
    const { xy, depth } = this.project(f.points);
    const focal = this.is3d ? this.camera.frame().focal : 0;
    // Perspective: a dot's size falls off with its distance from the camera.
    const radius = (i) => (depth ? Math.max(1.5, Math.min(7, (spacing * 0.22 * focal) / depth[i])) : r2d);
    const base = formationColors(f);
    // Light effects previewed at a show time (issue 18): the effects panel paints the colours.
    const colors = (!ghost && this.colorOverride && this.colorOverride(f, base)) || base;
    const sel = this.state.selection;
    // Draw far points first so nearer ones (smaller depth toward the viewer) stay on top.
    const order = f.points.map((_, i) => i);
    if (depth) order.sort((i, j) => depth[j] - depth[i]);
    else if (!ghost && this.view === "front") order.sort((i, j) => f.points[j][1] - f.points[i][1]);
    else if (!ghost && this.view === "side") order.sort((i, j) => f.points[i][0] - f.points[j][0]);
    for (const i of order) {
      const x = xy[2 * i];
      const y = xy[2 * i + 1];
      if (x < -10 || y < -10 || x > this.width + 10 || y > this.height + 10 || (depth && depth[i] <= 0)) continue;
      const r = radius(i);
      if (ghost) {
        ctx.strokeStyle = "rgba(140, 150, 180, 0.25)";
        ctx.beginPath();
        ctx.arc(x, y, r, 0, 2 * Math.PI);
        ctx.stroke();
        continue;
      }
      ctx.fillStyle = colors[i];
      ctx.beginPath();
      ctx.arc(x, y, r, 0, 2 * Math.PI);
      ctx.fill();
      if (this.close.has(i) || this.flagged.has(i)) {
        ctx.strokeStyle = "#ff3b5c";
        ctx.lineWidth = 2;
        ctx.beginPath();
        ctx.arc(x, y, r + 3, 0, 2 * Math.PI);
        ctx.stroke();
      }
      if (sel.has(i)) {
        ctx.strokeStyle = "#ffd166";
        ctx.lineWidth = 2;
        ctx.strokeRect(x - r - 2, y - r - 2, 2 * r + 4, 2 * r + 4);
      }
      ctx.lineWidth = 1;
    }
    if (!ghost && this.close.size) {
      // Spacing radius around close points: how far apart they must be.
      ctx.strokeStyle = "rgba(255, 59, 92, 0.35)";
      ctx.setLineDash([3, 3]);
      for (const i of this.close) {
        if (!f.points[i] || (depth && depth[i] <= 0)) continue;
        const x = xy[2 * i];
        const y = xy[2 * i + 1];
        ctx.beginPath();
        ctx.arc(x, y, (spacing / 2) * (depth ? focal / depth[i] : this.scale), 0, 2 * Math.PI);
        ctx.stroke();
      }
      ctx.setLineDash([]);
    }
  }

  _drawOverlay() {
    const { ctx } = this;
    const { strokes, box, preview } = this.overlay;
    ctx.strokeStyle = "#4dd6ff";
    ctx.lineWidth = 2;
    for (const s of strokes) {
      if (s.length < 2) continue;
      ctx.beginPath();
      s.forEach(([u, v], k) => {
        const [x, y] = this.toScreen(u, v);
        if (k) ctx.lineTo(x, y);
        else ctx.moveTo(x, y);
      });
      ctx.stroke();
    }
    ctx.lineWidth = 1;
    if (preview) {
      preview.uv.forEach(([u, v], i) => {
        const [x, y] = this.toScreen(u, v);
        ctx.fillStyle = preview.close.has(i) ? "#ff3b5c" : "#e6ebf5";
        ctx.beginPath();
        ctx.arc(x, y, preview.close.has(i) ? 3.5 : 2.5, 0, 2 * Math.PI);
        ctx.fill();
      });
    }
    if (box) {
      ctx.strokeStyle = "#ffd166";
      ctx.fillStyle = "rgba(255, 209, 102, 0.08)";
      ctx.setLineDash([4, 3]);
      const x = Math.min(box.x0, box.x1);
      const y = Math.min(box.y0, box.y1);
      ctx.fillRect(x, y, Math.abs(box.x1 - box.x0), Math.abs(box.y1 - box.y0));
      ctx.strokeRect(x, y, Math.abs(box.x1 - box.x0), Math.abs(box.y1 - box.y0));
      ctx.setLineDash([]);
    }
  }
}
