// @ts-check
// The launch-layout panel (issue 21 item 4): home positions from a grid, from a CSV file or from launch
// boxes holding several drones, with a preview of the layout and of the takeoff waves.
//
// The positions mirror formations/_launch.py (LaunchBoxes.positions_m) and the waves preview mirrors
// sim/plan/_waves.py: homes closer than max(min distance, downwash radius) cannot climb together; a
// greedy colouring (largest degree first) gives the waves. The planner's DSatur count and the exact
// timing come with the next check (the timeline shows them).

import { markRange } from "./settings.js";

// (api.js is imported when a CSV is imported: it starts a session on import, which node's unit tests must not.)

/**
 * Home positions of a show document and the launch box of each (-1: loose), drone i at row i.
 * @param {any} show
 * @returns {{points: number[][], box: number[]}}
 */
export function homePositions(show) {
  const home = (show && show.home) || {};
  if (home.grid) {
    const g = home.grid;
    const c = g.center_m || [0, 0];
    const points = [];
    for (let r = 0; r < g.rows; r++) {
      for (let k = 0; k < g.cols; k++) points.push([(k - (g.cols - 1) / 2) * g.spacing_m + c[0], (r - (g.rows - 1) / 2) * g.spacing_m + c[1], 0]);
    }
    return { points, box: points.map(() => -1) };
  }
  if (home.boxes) return boxPositions(home.boxes);
  const points = home.points || [];
  return { points, box: points.map(() => -1) };
}

/**
 * Positions of a `home.boxes` layout: box by box, each box's pattern in rows of `cols`, centred.
 * @param {{per_box: number, cols?: number, spacing_m: number, grid?: any, centers?: number[][]}} b
 * @returns {{points: number[][], box: number[]}}
 */
export function boxPositions(b) {
  const cols = Math.min(b.cols || Math.ceil(Math.sqrt(b.per_box)), b.per_box);
  const rows = Math.ceil(b.per_box / cols);
  /** @type {number[][]} */
  let centres = b.centers || [];
  if (b.grid) {
    const g = b.grid;
    const c = g.center_m || [0, 0];
    centres = [];
    for (let r = 0; r < g.rows; r++) {
      for (let k = 0; k < g.cols; k++) centres.push([(k - (g.cols - 1) / 2) * g.spacing_m + c[0], (r - (g.rows - 1) / 2) * g.spacing_m + c[1]]);
    }
  }
  const points = [];
  const box = [];
  centres.forEach((c, bi) => {
    for (let k = 0; k < b.per_box; k++) {
      points.push([c[0] + ((k % cols) - (cols - 1) / 2) * b.spacing_m, c[1] + (Math.floor(k / cols) - (rows - 1) / 2) * b.spacing_m, 0]);
      box.push(bi);
    }
  });
  return { points, box };
}

/**
 * Takeoff waves preview: greedy colouring (largest degree first) of the homes closer than `need` metres.
 * @param {number[][]} points the drones' homes
 * @param {number} need metres
 * @returns {{waves: number, wave: number[]}}
 */
export function previewWaves(points, need) {
  const n = points.length;
  /** @type {number[][]} */
  const nbrs = Array.from({ length: n }, () => []);
  // Cell hash of side `need`: only neighbouring cells can hold a conflict.
  const cells = new Map();
  const key = (/** @type {number} */ x, /** @type {number} */ y) => `${x},${y}`;
  points.forEach((p, i) => {
    const k = key(Math.floor(p[0] / need), Math.floor(p[1] / need));
    if (!cells.has(k)) cells.set(k, []);
    cells.get(k).push(i);
  });
  points.forEach((p, i) => {
    const cx = Math.floor(p[0] / need);
    const cy = Math.floor(p[1] / need);
    for (let dx = -1; dx <= 1; dx++) {
      for (let dy = -1; dy <= 1; dy++) {
        for (const j of cells.get(key(cx + dx, cy + dy)) || []) {
          if (j !== i && Math.hypot(points[j][0] - p[0], points[j][1] - p[1]) < need * (1 - 1e-9)) nbrs[i].push(j);
        }
      }
    }
  });
  const order = [...Array(n).keys()].sort((a, b) => nbrs[b].length - nbrs[a].length || a - b);
  const wave = new Array(n).fill(-1);
  for (const v of order) {
    const used = new Set(nbrs[v].map((u) => wave[u]));
    let c = 0;
    while (used.has(c)) c++;
    wave[v] = c;
  }
  return { waves: n ? Math.max(...wave) + 1 : 0, wave };
}

/** The launch-box fields, each with the show file's limits as min/max (formations/_launch.py). */
const LAUNCH_FIELDS = ["launch-per-box", "launch-box-cols", "launch-box-spacing", "launch-grid-spacing"];

/** Binds the launch-layout panel to the open show. */
export class LaunchPanel {
  /**
   * @param {HTMLElement} root the panel body
   * @param {import("./state.js").EditorState} state
   */
  constructor(root, state) {
    this.root = root;
    this.state = state;
    this.$ = (/** @type {string} */ id) => /** @type {HTMLInputElement} */ (root.querySelector(`#${id}`));
    this.$("launch-apply").addEventListener("click", () => this.applyBoxes());
    this.$("launch-grid").addEventListener("click", () => this.applyGrid());
    this.$("launch-csv").addEventListener("change", () => this.importCsv());
    for (const id of LAUNCH_FIELDS) this.$(id).addEventListener("change", () => this._markFields());
    state.addEventListener("change", (/** @type {any} */ e) => {
      if (["load", "edit"].includes(e.detail.kind)) this.render();
    });
  }

  _error(msg) {
    const el = this.root.querySelector("#launch-error");
    if (el) el.textContent = msg;
  }

  /**
   * Mark the box fields outside the show file's limits (their min/max) at once, naming the first in the error
   * line, as the settings fields are marked. @returns {string} the message ("" when all are inside)
   */
  _markFields() {
    let first = "";
    for (const id of LAUNCH_FIELDS) {
      const input = this.$(id);
      const v = Number(input.value);
      const msg = input.value === "" || !Number.isFinite(v) ? "" : markRange(input, v);
      if (msg && !first) first = `${this.root.querySelector(`label[for="${id}"]`)?.textContent || id}: ${msg}`;
    }
    this._error(first);
    return first;
  }

  /** Replace the home layout by launch boxes from the form (one undo step). */
  applyBoxes() {
    const st = this.state;
    if (!st.show) return;
    const num = (/** @type {string} */ id) => Number(this.$(id).value);
    const perBox = Math.round(num("launch-per-box"));
    const boxes = Math.max(1, Math.ceil(st.show.drones / Math.max(perBox, 1)));
    const cols = Math.ceil(Math.sqrt(boxes));
    /** @type {any} */
    const layout = {
      per_box: perBox, spacing_m: num("launch-box-spacing"),
      grid: { rows: Math.ceil(boxes / cols), cols, spacing_m: num("launch-grid-spacing") },
    };
    const boxCols = Math.round(num("launch-box-cols"));
    if (boxCols > 0) layout.cols = boxCols;
    this._markFields();
    st.edit("Set launch boxes", () => { st.show.home = { boxes: layout }; });
  }

  /** Back to a square home grid at the minimum distance (one undo step). */
  applyGrid() {
    const st = this.state;
    if (!st.show) return;
    const cols = Math.ceil(Math.sqrt(st.show.drones));
    const spacing = Math.max(st.show.settings.min_distance_m, 0.1);
    st.edit("Set a home grid", () => { st.show.home = { grid: { rows: Math.ceil(st.show.drones / cols), cols, spacing_m: spacing } }; });
  }

  /** Home points from the chosen CSV file, read by the server (its errors name the line). */
  async importCsv() {
    const st = this.state;
    const file = this.$("launch-csv").files?.[0];
    if (!st.show || !file) return;
    this._error("");
    try {
      const api = await import("./api.js");
      const res = /** @type {any} */ (await api.request("POST", "/api/formations/home-csv", { body: (() => {
        const fd = new FormData();
        fd.append("file", file);
        return fd;
      })() }));
      st.edit(`Import ${res.count} home positions`, () => { st.show.home = { points: res.points }; });
    } catch (e) {
      this._error(e instanceof Error ? e.message : String(e));
    } finally {
      this.$("launch-csv").value = "";
    }
  }

  /** Fill the form and draw the preview. */
  render() {
    const show = this.state.show;
    const out = /** @type {HTMLElement} */ (this.root.querySelector("#launch-summary"));
    if (!show) {
      out.textContent = "";
      return;
    }
    const b = show.home.boxes;
    if (b) {
      this.$("launch-per-box").value = String(b.per_box);
      this.$("launch-box-spacing").value = String(b.spacing_m);
      this.$("launch-box-cols").value = b.cols ? String(b.cols) : "";
      if (b.grid) this.$("launch-grid-spacing").value = String(b.grid.spacing_m);
      this._markFields();
    }
    const { points, box } = homePositions(show);
    const mine = points.slice(0, show.drones);
    const s = show.settings || {};
    const need = Math.max(s.min_distance_m ?? 3, s.downwash_radius_m ?? s.min_distance_m ?? 3);
    const { waves, wave } = previewWaves(mine, need);
    const kind = show.home.grid ? "grid" : show.home.boxes ? `${new Set(box).size} launch boxes of ${b.per_box}` : "points";
    out.textContent = `${mine.length} home positions (${kind}); takeoff ${waves <= 1 ? "all at once" : `in ${waves} waves, one drone of each box after another`}.`;
    this._draw(mine, wave, Math.max(waves, 1));
  }

  /**
   * @param {number[][]} pts @param {number[]} wave @param {number} waves
   */
  _draw(pts, wave, waves) {
    const canvas = /** @type {HTMLCanvasElement} */ (this.root.querySelector("#launch-preview"));
    const ctx = canvas.getContext("2d");
    if (!ctx) return;
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    if (!pts.length) return;
    const xs = pts.map((p) => p[0]);
    const ys = pts.map((p) => p[1]);
    const x0 = Math.min(...xs);
    const y0 = Math.min(...ys);
    const span = Math.max(Math.max(...xs) - x0, Math.max(...ys) - y0, 1);
    const k = (Math.min(canvas.width, canvas.height) - 16) / span;
    pts.forEach((p, i) => {
      // wave colour: early waves warm, late waves cool
      ctx.fillStyle = `hsl(${Math.round((240 * wave[i]) / Math.max(waves - 1, 1))}, 70%, 55%)`;
      ctx.beginPath();
      ctx.arc(8 + (p[0] - x0) * k, canvas.height - 8 - (p[1] - y0) * k, 2.5, 0, 2 * Math.PI);
      ctx.fill();
    });
  }
}
