// @ts-check
// "Motion during the hold" (issue 21 item 5): a formation's keyframed rotation, translation and
// scale about a pivot over its hold (the show file's `motion`, formations/_motion.py). The panel
// sets a motion in one step (rotate N° about x/y/z, translate, scale, over the whole hold), lists
// the keys for editing, and plays the motion on the canvas. The interpolation is the server's:
// each channel (translate x/y/z, Euler angles about the fixed x, then y, then z axes, scale) is a
// quintic Hermite per key interval with zero end accelerations; a "smooth" key stops, a
// "linear" key goes through at the rate of its neighbours' chord; the first and last keys stop.
// The planner verifies the flown pieces; this only draws the motion.

import { setError } from "./errors.js";

const DEG = Math.PI / 180;
/** Longest a canvas playback lasts, seconds (longer holds play faster). */
const MAX_PLAY_S = 8;

/**
 * The seven channels [tx, ty, tz, rx, ry, rz (radians), s] at hold time `t` (clamped to the keys).
 * @param {{keys: any[]}} motion
 * @param {number} t seconds into the hold
 * @returns {number[]}
 */
export function channelsAt(motion, t) {
  const keys = motion.keys;
  const q = keys.map((k) => [...(k.translate_m || [0, 0, 0]), ...(k.rotate_deg || [0, 0, 0]).map((d) => d * DEG), k.scale ?? 1]);
  const ts = keys.map((k) => k.t_s);
  const last = keys.length - 1;
  if (t <= ts[0]) return q[0].slice();
  if (t >= ts[last]) return q[last].slice();
  let i = 0;
  while (i < last - 1 && ts[i + 1] <= t) i++;
  const vel = (/** @type {number} */ k) => q[k].map((_, c) => (k > 0 && k < last && keys[k].easing === "linear"
    ? (q[k + 1][c] - q[k - 1][c]) / (ts[k + 1] - ts[k - 1]) : 0));
  const h = ts[i + 1] - ts[i];
  const u = (t - ts[i]) / h;
  const h00 = 1 - 10 * u ** 3 + 15 * u ** 4 - 6 * u ** 5;
  const h10 = u - 6 * u ** 3 + 8 * u ** 4 - 3 * u ** 5;
  const h01 = 10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5;
  const h11 = -4 * u ** 3 + 7 * u ** 4 - 3 * u ** 5;
  const v0 = vel(i);
  const v1 = vel(i + 1);
  return q[i].map((p0, c) => h00 * p0 + h10 * v0[c] * h + h01 * q[i + 1][c] + h11 * v1[c] * h);
}

/**
 * The pivot: `pivot_m`, or the centroid of the formation's points.
 * @param {{pivot_m?: number[]|null}} motion
 * @param {number[][]} points
 * @returns {number[]}
 */
export function pivotOf(motion, points) {
  if (motion.pivot_m) return motion.pivot_m.slice();
  const c = [0, 0, 0];
  for (const p of points) for (let a = 0; a < 3; a++) c[a] += p[a] / points.length;
  return c;
}

/**
 * The formation's points moved to hold time `t`: c + s·R_z R_y R_x (p - c) + T.
 * @param {{keys: any[], pivot_m?: number[]|null}} motion
 * @param {number[][]} points
 * @param {number} t seconds into the hold
 * @returns {number[][]}
 */
export function movedPoints(motion, points, t) {
  const [tx, ty, tz, rx, ry, rz, s] = channelsAt(motion, t);
  const c = pivotOf(motion, points);
  const [cx, sx, cy, sy, cz, sz] = [Math.cos(rx), Math.sin(rx), Math.cos(ry), Math.sin(ry), Math.cos(rz), Math.sin(rz)];
  // R = R_z R_y R_x, row by row.
  const r = [
    [cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
    [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
    [-sy, cy * sx, cy * cx],
  ];
  return points.map((p) => {
    const d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
    return [0, 1, 2].map((a) => c[a] + s * (r[a][0] * d[0] + r[a][1] * d[1] + r[a][2] * d[2]) + [tx, ty, tz][a]);
  });
}

/** The Motion section of the left sidebar. */
export class MotionPanel {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {import("./canvas.js").CanvasView} view
   */
  constructor(state, view) {
    this.state = state;
    this.view = view;
    this.table = /** @type {HTMLTableElement} */ (document.getElementById("motion-keys"));
    this.info = document.getElementById("motion-info");
    this.playButton = /** @type {HTMLButtonElement} */ (document.getElementById("btn-motion-play"));
    /** @type {number|null} */
    this._frame = null;
    const num = (/** @type {string} */ id) => Number(/** @type {HTMLInputElement} */ (document.getElementById(id)).value);
    document.getElementById("btn-motion-set").addEventListener("click", () => {
      const f = state.formation;
      if (!f) return;
      setError("motion", "");
      const deg = num("motion-rotate");
      const axis = Number(/** @type {HTMLSelectElement} */ (document.getElementById("motion-axis")).value);
      const move = [num("motion-tx"), num("motion-ty"), num("motion-tz")];
      const scale = num("motion-scale");
      if (![deg, scale, ...move].every(Number.isFinite) || !(scale > 0)) {
        setError("motion", "Rotation, translation and scale must be numbers, and the scale > 0.");
        return;
      }
      const rotate = [0, 0, 0];
      rotate[axis] = deg;
      state.edit(`Motion: rotate ${deg}° about ${"xyz"[axis]} over the hold`, () => {
        state.formation.motion = {
          keys: [{ t_s: 0 }, { t_s: f.hold_s, rotate_deg: rotate, translate_m: move, scale }],
        };
      });
    });
    document.getElementById("btn-motion-key").addEventListener("click", () => this.addKey());
    document.getElementById("btn-motion-clear").addEventListener("click", () => {
      if (!state.formation || !state.formation.motion) return;
      state.edit("Remove the motion", () => { delete state.formation.motion; });
    });
    this.playButton.addEventListener("click", () => (this._frame != null ? this.stop() : this.play()));
    state.addEventListener("change", (/** @type {any} */ e) => {
      if (e.detail.kind === "selection") return;
      if (e.detail.kind !== "edit") this.stop();
      this.render();
    });
    this.render();
  }

  /** Insert a key halfway through the last key interval, at the motion's pose there (the motion keeps its path). */
  addKey() {
    const f = this.state.formation;
    if (!f || !f.motion) return;
    const keys = f.motion.keys;
    const a = keys[keys.length - 2].t_s;
    const b = keys[keys.length - 1].t_s;
    const t = +((a + b) / 2).toFixed(3);
    const [tx, ty, tz, rx, ry, rz, s] = channelsAt(f.motion, t);
    const r = (/** @type {number} */ v) => +v.toFixed(4);
    this.state.edit(`Motion: add a key at ${t} s`, () => {
      this.state.formation.motion.keys.splice(keys.length - 1, 0, {
        t_s: t, translate_m: [tx, ty, tz].map(r), rotate_deg: [rx, ry, rz].map((v) => r(v / DEG)), scale: r(s),
        easing: "linear",
      });
    });
  }

  /** Rebuild the key table for the current formation. */
  render() {
    const f = this.state.formation;
    const motion = f && f.motion;
    this.table.replaceChildren();
    this.playButton.disabled = !motion;
    document.getElementById("btn-motion-key").toggleAttribute("disabled", !motion);
    document.getElementById("btn-motion-clear").toggleAttribute("disabled", !motion);
    if (this._frame == null) this.info.textContent = motion ? `${motion.keys.length} keys over the hold` : "holds still";
    if (!motion) return;
    motion.keys.forEach((key, i) => {
      // One block per key: time, scale, easing and delete; then the translation; then the rotation.
      const body = document.createElement("tbody");
      body.className = "motion-key";
      body.setAttribute("aria-label", `Motion key ${i + 1}`);
      const line = (/** @type {string} */ label, /** @type {(HTMLElement|Text)[]} */ ...els) => {
        const tr = document.createElement("tr");
        const th = document.createElement("th");
        th.textContent = label;
        const td = document.createElement("td");
        td.append(...els);
        tr.append(th, td);
        body.append(tr);
      };
      const input = (/** @type {number} */ value, /** @type {string} */ label, /** @type {(v: number, k: any) => void} */ set) => {
        const el = document.createElement("input");
        el.type = "number";
        el.step = "any";
        el.value = String(value);
        el.title = label;
        el.setAttribute("aria-label", `Key ${i + 1} ${label}`);
        el.addEventListener("change", () => setTimeout(() => {
          const v = Number(el.value);
          if (el.value === "" || !Number.isFinite(v)) { el.value = String(value); return; }
          this.state.edit(`Motion key ${i + 1}: ${label}`, () => set(v, this.state.formation.motion.keys[i]));
        }));
        return el;
      };
      const ease = document.createElement("select");
      ease.setAttribute("aria-label", `Key ${i + 1} easing`);
      for (const name of ["smooth", "linear"]) ease.append(new Option(name, name, false, (key.easing || "smooth") === name));
      ease.title = "smooth: the motion stops at this key; linear: it goes through (the first and last keys always stop)";
      ease.addEventListener("change", () => this.state.edit(`Motion key ${i + 1}: ${ease.value}`, () => {
        this.state.formation.motion.keys[i].easing = ease.value;
      }));
      const del = document.createElement("button");
      del.type = "button";
      del.textContent = "✕";
      del.disabled = motion.keys.length <= 2;
      del.setAttribute("aria-label", `Delete motion key ${i + 1}`);
      del.addEventListener("click", () => this.state.edit(`Motion: delete key ${i + 1}`, () => {
        this.state.formation.motion.keys.splice(i, 1);
      }));
      line(`key ${i + 1} at`, input(key.t_s, "time, seconds", (v, k) => { k.t_s = v; }), document.createTextNode(" s "),
        ease, del);
      line("move (m)", ...[0, 1, 2].map((a) => input((key.translate_m || [0, 0, 0])[a], `translate ${"xyz"[a]}, metres`,
        (v, k) => {
          k.translate_m = (k.translate_m || [0, 0, 0]).slice();
          k.translate_m[a] = v;
        })));
      line("turn (°)", ...[0, 1, 2].map((a) => input((key.rotate_deg || [0, 0, 0])[a], `rotate about ${"xyz"[a]}, degrees`,
        (v, k) => {
          k.rotate_deg = (k.rotate_deg || [0, 0, 0]).slice();
          k.rotate_deg[a] = v;
        })));
      line("scale", input(key.scale ?? 1, "scale", (v, k) => { k.scale = v; }));
      this.table.append(body);
    });
  }

  /** Play the current formation's motion on the canvas (at most MAX_PLAY_S long). */
  play() {
    const f = this.state.formation;
    if (!f || !f.motion) return;
    const end = f.motion.keys[f.motion.keys.length - 1].t_s;
    const speed = Math.max(1, end / MAX_PLAY_S);
    const t0 = performance.now();
    this.playButton.textContent = "■ Stop";
    const step = () => {
      const g = this.state.formation;
      if (!g || !g.motion) { this.stop(); return; }
      const t = Math.min(end, ((performance.now() - t0) / 1000) * speed);
      this.view.moved = (/** @type {any} */ h) => (h === g ? { ...h, points: movedPoints(g.motion, g.points, t) } : h);
      this.info.textContent = `t = ${t.toFixed(1)} s of the hold${speed > 1 ? ` (×${speed.toFixed(1)})` : ""}`;
      this.view.redraw();
      if (t >= end) { this._frame = null; this.playButton.textContent = "▶ Play"; return; }
      this._frame = requestAnimationFrame(step);
    };
    this._frame = requestAnimationFrame(step);
  }

  /** Stop a playback and draw the formation at rest again. */
  stop() {
    if (this._frame != null) cancelAnimationFrame(this._frame);
    this._frame = null;
    if (this.playButton) this.playButton.textContent = "▶ Play";
    if (this.view.moved) {
      this.view.moved = null;
      this.view.redraw();
    }
  }
}
