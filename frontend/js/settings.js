// @ts-check
// The show settings form: name, drone count, home grid and the safety limits, bound to the
// document (each change is one undo step).

import { flyingCount } from "./groups.js";
import { choose } from "./dialogs.js";
import { fitToCount } from "./geometry.js";
import { repairSpacing } from "./spacing.js";

function getPath(obj, path) {
  return path.split(".").reduce((o, k) => (o == null ? undefined : o[k]), obj);
}

function setPath(obj, path, value) {
  const keys = path.split(".");
  const last = keys.pop();
  const target = keys.reduce((o, k) => (o[k] ??= {}), obj);
  target[last] = value;
}

/** The show file's cap on home positions: at most 4 per drone, and 16 for a small show (formations/_show.py). */
const homeSlots = (/** @type {number} */ n) => Math.max(4 * n, 16);

/** The about-square grid for `n` drones (as the new-show form makes). @param {number} n */
function squareGrid(n) {
  const cols = Math.ceil(Math.sqrt(n));
  return { rows: Math.ceil(n / cols), cols };
}

/**
 * The home grid after the drone count changed from `oldN` to `newN`: the about-square grid for `newN` when
 * the grid no longer holds the drones, has more positions than the show file allows, or was the square grid
 * of `oldN` (so a count typed by mistake and typed again gives the grid back); else the designer's grid.
 * @param {{rows: number, cols: number}} grid @param {number} oldN @param {number} newN
 * @returns {any} a new grid object (spacing and centre kept)
 */
export function homeGridFor(grid, oldN, newN) {
  const slots = grid.rows * grid.cols;
  const auto = squareGrid(oldN);
  const square = grid.rows === auto.rows && grid.cols === auto.cols;
  if (slots >= newN && slots <= homeSlots(newN) && !square) return { ...grid };
  return { ...grid, ...squareGrid(newN) };
}

/**
 * Fit every formation with fewer points than drones to the drone count (one undo step).
 * @param {import("./state.js").EditorState} state
 * @returns {number} how many formations changed
 */
export function fitAllFormations(state) {
  const n = state.show.drones;
  // A subset formation (issue 21) needs points for the drones that fly it only.
  const need = (/** @type {any} */ f) => flyingCount(state.show, f);
  const short = state.show.formations.filter((f) => f.points.length < need(f)).length;
  if (!short) return 0;
  state.edit(`Fit ${short} formation${short > 1 ? "s" : ""} to ${n} drones`, () => {
    for (const f of state.show.formations) {
      if (f.points.length >= need(f)) continue;
      const fit = fitToCount(f.points, f.colors, need(f));
      const fixed = repairSpacing(fit.points, state.show.settings.min_distance_m);
      f.points = fixed.points.map((p) => p.map((v) => Math.round(v * 1000) / 1000));
      f.colors = fit.colors;
    }
    state.selection = new Set();
  });
  return short;
}

/**
 * Mark a number field whose value is outside its own `min`/`max` (the show file's limits, kept on the input),
 * as the save would name it: "at least lo" / "at most hi" in `errorEl` and the `has-error` class; cleared
 * when inside. `data-exclusive="min"`, `"max"` or `"min max"`: that bound is strict (a rule's gt / lt), said
 * "more than lo" / "less than hi".
 * @param {HTMLInputElement} input @param {number} value @param {Element|null} [errorEl]
 * @returns {string} the message ("" inside the range)
 */
export function markRange(input, value, errorEl) {
  const lo = input.min !== "" ? Number(input.min) : -Infinity;
  const hi = input.max !== "" ? Number(input.max) : Infinity;
  const strict = (input.dataset.exclusive || "").split(" ");
  const msg = strict.includes("min") ? (value <= lo ? `more than ${lo}` : "") : value < lo ? `at least ${lo}` : "";
  const over = strict.includes("max") ? (value >= hi ? `less than ${hi}` : "") : value > hi ? `at most ${hi}` : "";
  const said = msg || over;
  input.classList.toggle("has-error", said !== "");
  if (errorEl) errorEl.textContent = said;
  return said;
}

/** Binds the settings form to the open show. */
export class SettingsForm {
  /**
   * @param {HTMLFormElement} form
   * @param {import("./state.js").EditorState} state
   */
  constructor(form, state) {
    this.form = form;
    this.state = state;
    /** @type {HTMLInputElement[]} */
    this.inputs = [...form.querySelectorAll("[data-path]")].map((el) => /** @type {HTMLInputElement} */ (el));
    /** @type {(() => Promise<unknown>)|null} fits every short formation (set by the editor) */
    this.fitAll = null;
    form.addEventListener("submit", (e) => e.preventDefault());
    for (const input of this.inputs) input.addEventListener("change", () => this._changed(input));
    state.addEventListener("change", (/** @type {any} */ e) => {
      if (["load", "edit"].includes(e.detail.kind)) this.render();
    });
  }

  /** Fill the form from the document. */
  render() {
    const show = this.state.show;
    this.form.querySelector("fieldset")?.toggleAttribute("disabled", !show);
    for (const input of this.inputs) {
      const v = show ? getPath(show, input.dataset.path) : "";
      input.value = v == null ? "" : String(v);
      input.disabled = !show || (input.dataset.path.startsWith("home.grid") && !(show.home && show.home.grid));
    }
  }

  /** The geofence's four edges: all set -> the fence (one undo step), all blank -> none. */
  _fenceChanged() {
    const st = this.state;
    const inputs = this.inputs.filter((i) => i.dataset.path.startsWith("settings.geofence."));
    const err = this.form.querySelector('[data-error-for="settings.geofence"]');
    err.textContent = "";
    if (inputs.every((i) => i.value === "")) {
      if (st.show.settings.geofence) st.edit("Remove the geofence", () => { delete st.show.settings.geofence; });
      return;
    }
    if (inputs.some((i) => i.value === "" || !Number.isFinite(Number(i.value)))) {
      err.textContent = "Give all four edges (or none for no geofence).";
      return;
    }
    const fence = Object.fromEntries(inputs.map((i) => [i.dataset.path.split(".").pop(), Number(i.value)]));
    if (!(fence.x_min_m < fence.x_max_m && fence.y_min_m < fence.y_max_m)) {
      err.textContent = "Each edge must be below its opposite one (x min < x max, y min < y max).";
      return;
    }
    st.edit("Set the geofence", () => { st.show.settings.geofence = fence; });
  }

  async _changed(input) {
    const st = this.state;
    if (!st.show) return;
    const path = input.dataset.path;
    if (path.startsWith("settings.geofence.")) return this._fenceChanged();
    const old = getPath(st.show, path);
    let value;
    if (input.type === "number") {
      value = Number(input.value);
      if (input.value === "" || !Number.isFinite(value)) {
        input.value = String(old);
        return;
      }
      if (["drones", "home.grid.rows", "home.grid.cols"].includes(path)) value = Math.round(value);
    } else {
      value = input.value.trim();
      if (!value) {
        input.value = String(old);
        return;
      }
    }
    if (value === old) return;
    input.classList.remove("has-error");
    // Outside the field's own range: applied (the save keeps it as a draft) and marked at once, as the save would.
    const errorEl = this.form.querySelector(`[data-error-for="${CSS.escape(path)}"]`);
    const outside = typeof value === "number" && markRange(input, value, errorEl) !== "";
    const label = input.getAttribute("aria-label") || path;
    st.edit(`Change ${label.toLowerCase()}`, () => {
      setPath(st.show, path, value);
      // A count the show file accepts: the home grid follows it (both ways; see homeGridFor).
      if (path === "drones" && st.show.home.grid && Number.isInteger(old) && value >= 1) {
        st.show.home.grid = homeGridFor(st.show.home.grid, old, value);
      }
    });
    // A count the show file refuses is not fitted (30000 points in every formation froze the tab).
    if (path === "drones" && !outside) {
      const short = st.show.formations.filter((f) => f.points.length < flyingCount(st.show, f)).length;
      if (short) {
        const { choice } = await choose({
          title: "Fewer points than drones",
          message: `${short} formation${short > 1 ? "s have" : " has"} fewer than ${value} points. Fit them to ${value} drones now?`,
          buttons: [{ label: "Fit them", value: "fit", primary: true }, { label: "Later", value: "later" }],
        });
        // Formations made from a source are made again at the new count (see Sources.fitAll).
        if (choice === "fit") await (this.fitAll ? this.fitAll() : fitAllFormations(st));
      }
    }
  }
}
