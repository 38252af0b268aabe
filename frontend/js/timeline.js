// @ts-check
// The timeline: formations in order with hold times and names; add, duplicate, drag to reorder,
// delete; the planned transition durations between them once the show has been checked.

import { toast } from "./dialogs.js";
import { flyingCount } from "./groups.js";
import { durationProblem, formationColors } from "./state.js";

/**
 * A valid starting formation: a near-square grid of `n` points facing the audience, spaced 1.5x
 * the minimum distance, above the takeoff altitude; if it would rise above the ceiling, the grid
 * is split into layers one behind the other (along y).
 * @param {any} show
 * @param {string} name
 * @returns {{name: string, hold_s: number, points: number[][], colors: string[]}}
 */
export function gridFormation(show, name) {
  const n = show.drones;
  const st = show.settings;
  const s = st.min_distance_m * 1.5;
  const bottom = Math.min(Math.max(st.takeoff_altitude_m + 10, 20), st.max_altitude_m / 2);
  const maxRows = Math.max(1, Math.floor((st.max_altitude_m - 5 - bottom) / s) + 1);
  const cols = Math.ceil(Math.sqrt(n));
  const rows = Math.min(Math.ceil(n / cols), maxRows);
  const layers = Math.ceil(n / (rows * cols));
  const points = [];
  for (let i = 0; i < n; i++) {
    const layer = Math.floor(i / (rows * cols));
    const r = Math.floor((i % (rows * cols)) / cols);
    const c = i % cols;
    points.push([
      +((c - (cols - 1) / 2) * s).toFixed(3),
      +((layer - (layers - 1) / 2) * s).toFixed(3),
      +(bottom + (rows - 1 - r) * s).toFixed(3),
    ]);
  }
  return { name, hold_s: 5, points, colors: points.map(() => "#ffffff") };
}

function uniqueName(show, base) {
  const names = new Set(show.formations.map((f) => f.name));
  if (!names.has(base)) return base;
  for (let k = 2; ; k++) if (!names.has(`${base} ${k}`)) return `${base} ${k}`;
}

/** Renders the formation list and turns its gestures into undoable edits. */
export class Timeline {
  /**
   * @param {HTMLOListElement} list
   * @param {import("./state.js").EditorState} state
   */
  constructor(list, state) {
    this.list = list;
    this.state = state;
    /** @type {Array<number|null>} planned transition duration into each formation, seconds */
    this.transitions = [];
    /** @type {Map<number, string>} problems per formation index (from save or check) */
    this.problems = new Map();
    this._dragFrom = -1;
    /** @type {((k: number) => void)|null} called when a transition is clicked */
    this.onTransition = null;
    /** @type {Array<number|null>} shortest admissible transition durations from the last check */
    this.minDurations = [];
    /** @type {Array<any|null>} the check of the transition into each formation (`by_transition` entry) */
    this.checks = [];
    /** @type {any[]} the checks of takeoff and of the way back (landing approach, landing) */
    this.ends = [];
    state.addEventListener("change", (/** @type {CustomEvent} */ e) => {
      if (e.detail.kind === "load") this.setCheck(0, [], []);
      // Switching formations only moves the highlight: rebuilding the cards would replace the
      // input that keyboard focus just reached (losing its select-all, so typing appended).
      if (e.detail.kind === "current") this._markCurrent();
      else if (e.detail.kind !== "selection" && e.detail.kind !== "live") this.render();
    });
  }

  /**
   * Take the timing of the last check: each transition's length, the stagger the planner added,
   * and whether it is safe.
   * @param {number} count number of formations
   * @param {any[]} groups the report's `by_transition`
   * @param {any[]} transitions the report's `transitions` (for the shortest admissible durations)
   */
  setCheck(count, groups, transitions) {
    this.checks = Array.from({ length: count }, (_, k) =>
      groups.find((g) => g.kind === "transition" && g.formation === k) || null);
    this.transitions = this.checks.map((g, k) => (g ? g.duration_s : transitions[k] ? transitions[k].duration_s : null));
    this.minDurations = this.checks.map((g) => {
      const t = g ? transitions.find((x) => x.segment === g.segment) : null;
      return t ? t.min_duration_s : null;
    });
    this.ends = groups.filter((g) => g.kind === "takeoff" || g.kind === "landing" || (g.kind === "transition" && g.formation < 0));
  }

  /**
   * Take the transition lengths of a plan (a simulation's: `{segments: [{kind, duration_s}]}`, the server's
   * plan summary) where no check has given them: a designer who simulates without checking sees the planned
   * durations too. The transition into formation k is the segment just before its hold.
   * @param {number} count number of formations
   * @param {{segments?: {kind: string, duration_s: number}[]}|null|undefined} plan
   */
  setPlanned(count, plan) {
    const segs = (plan && plan.segments) || [];
    const holds = segs.map((s, i) => (s.kind === "hold" ? i : -1)).filter((i) => i >= 0);
    if (holds.length !== count) return; // not this show's plan (a formation added or removed since)
    this.transitions = holds.map((i, k) => {
      if (this.checks[k]) return this.transitions[k];
      const before = segs[i - 1];
      return before && before.kind === "transition" ? before.duration_s : null;
    });
  }

  /** Add a new grid formation after the current one. */
  add() {
    const st = this.state;
    if (!st.show) return;
    st.edit("Add formation", () => {
      const f = gridFormation(st.show, uniqueName(st.show, `Formation ${st.show.formations.length + 1}`));
      st.show.formations.splice(st.current + 1, 0, f);
      st.current += 1;
      st.selection = new Set();
    });
  }

  /** Duplicate the current formation. */
  duplicate() {
    const st = this.state;
    if (!st.formation) return;
    st.edit("Duplicate formation", () => {
      const copy = structuredClone(st.formation);
      copy.name = uniqueName(st.show, `${copy.name} copy`);
      st.show.formations.splice(st.current + 1, 0, copy);
      st.current += 1;
      st.selection = new Set();
    });
  }

  /** Delete the current formation (a show keeps at least one). */
  remove() {
    const st = this.state;
    if (!st.show || st.show.formations.length <= 1) return false;
    st.edit(`Delete formation "${st.formation.name}"`, () => {
      st.show.formations.splice(st.current, 1);
      st.current = Math.min(st.current, st.show.formations.length - 1);
      st.selection = new Set();
    });
    return true;
  }

  /**
   * Move a formation to another place in the order.
   * @param {number} from @param {number} to
   */
  move(from, to) {
    const st = this.state;
    const n = st.show ? st.show.formations.length : 0;
    if (from === to || from < 0 || to < 0 || from >= n || to >= n) return;
    st.edit("Reorder formations", () => {
      const [f] = st.show.formations.splice(from, 1);
      st.show.formations.splice(to, 0, f);
      st.current = to;
      st.selection = new Set();
    });
  }

  /**
   * Fix (or free) the duration of the transition into formation `k`.
   * @param {number} k
   * @param {number|null} seconds null: planned automatically (as fast as the limits allow)
   */
  setTransition(k, seconds) {
    const st = this.state;
    st.edit(seconds == null ? "Automatic transition" : `Transition ${seconds} s`, () => {
      const f = st.show.formations[k];
      if (seconds == null) delete f.transition_s;
      else f.transition_s = seconds;
    });
  }

  /** Move the current-formation highlight to `state.current` without rebuilding the list. */
  _markCurrent() {
    for (const li of this.list.querySelectorAll(".tl-card")) {
      if (Number(/** @type {HTMLElement} */ (li).dataset.index) === this.state.current) li.setAttribute("aria-current", "true");
      else li.removeAttribute("aria-current");
    }
  }

  /** Rebuild the list. */
  render() {
    const st = this.state;
    const list = this.list;
    // Keep keyboard focus on the same control across the rebuild.
    const active = list.contains(document.activeElement) ? document.activeElement.getAttribute("aria-label") : null;
    list.replaceChildren();
    if (!st.show) return;
    const total = document.getElementById("timeline-total");
    const holds = st.show.formations.reduce((a, f) => a + f.hold_s, 0);
    const moves = this.transitions.filter((t) => t != null).reduce((a, b) => a + b, 0);
    if (total) total.textContent = `${st.show.formations.length} formations · holds ${holds.toFixed(1)} s${moves ? ` · transitions ${moves.toFixed(1)} s` : ""}`;
    const before = this.ends.filter((g) => g.kind === "takeoff");
    const after = this.ends.filter((g) => g.kind !== "takeoff");
    if (before.length) list.append(this._endItem("↑ takeoff", before));
    st.show.formations.forEach((f, k) => {
      const tr = document.createElement("li");
      tr.className = "tl-transition";
      const b = document.createElement("button");
      b.type = "button";
      const dur = this.transitions[k];
      const g = this.checks[k];
      const fixed = f.transition_s != null;
      const stagger = g && g.stagger_s > 0 ? ` +${g.stagger_s.toFixed(1)} s stagger` : "";
      b.classList.toggle("fixed", fixed);
      b.classList.toggle("unsafe", !!g && !g.ok);
      b.textContent = (fixed ? `→ ${f.transition_s} s fixed` : dur != null ? `→ ${dur.toFixed(1)} s` : "→") + stagger + (g && !g.ok ? " ⚠" : "");
      // A longer duration moves nobody apart (the planner's lines do not depend on it): say so
      // instead of inviting it when drones come too close.
      const close = g && (g.violations || []).some((v) => v.kind === "min_distance");
      b.title = (dur != null ? `Planned transition into "${f.name}": ${dur.toFixed(2)} s${stagger ? `, of which ${g.stagger_s.toFixed(2)} s stagger the planner added` : ""}. ` : "Check the show to plan transitions. ") +
        (g && !g.ok ? `${g.violations_total} violation(s)${g.fixes && g.fixes.length ? `; would fix it: ${g.fixes.join("; ")}` : ""}. ` : "") +
        (close ? "A different duration does not separate these drones. " : "") + "Click to set its duration.";
      b.setAttribute("aria-label", `Transition into formation ${k + 1}${dur != null ? `: ${dur.toFixed(1)} s planned` : ""}${stagger ? `,${stagger}` : ""}${fixed ? `, fixed at ${f.transition_s} s` : ""}${g && !g.ok ? `, ${g.violations_total} violations` : ""}; set its duration`);
      b.addEventListener("click", () => this.onTransition && this.onTransition(k));
      tr.append(b);
      list.append(tr);
      list.append(this._card(f, k));
    });
    if (after.length) list.append(this._endItem("↓ landing", after));
    if (active) {
      for (const el of list.querySelectorAll("[aria-label]")) {
        if (el.getAttribute("aria-label") === active) {
          /** @type {HTMLElement} */ (el).focus();
          break;
        }
      }
    }
  }

  /**
   * Takeoff or the way back as a plain item: total length, stagger, and whether it is safe.
   * @param {string} label
   * @param {any[]} groups
   */
  _endItem(label, groups) {
    const li = document.createElement("li");
    li.className = "tl-end";
    const dur = groups.reduce((a, g) => a + g.duration_s, 0);
    const stagger = groups.reduce((a, g) => a + (g.stagger_s || 0), 0);
    const bad = groups.filter((g) => !g.ok);
    // Launch boxes: takeoff / landing in waves (one drone of each box per wave), how many and how long.
    const waves = groups.reduce((a, g) => Math.max(a, g.waves || 0), 0);
    const waved = groups.filter((g) => (g.waves || 0) > 0).reduce((a, g) => a + g.duration_s, 0);
    const wavesText = waves > 0 ? ` · ${waves} waves` : "";
    li.classList.toggle("unsafe", bad.length > 0);
    li.textContent = `${label} ${dur.toFixed(1)} s${wavesText}${stagger > 0 ? ` +${stagger.toFixed(1)} s stagger` : ""}${bad.length ? " ⚠" : ""}`;
    const fixes = bad.flatMap((g) => g.fixes || []);
    li.title = `${label.slice(2)}: ${dur.toFixed(2)} s${waves > 0 ? `; ${waves} waves over ${waved.toFixed(1)} s (drones of a launch box leave one after another)` : ""}${bad.length ? `; ${bad.reduce((a, g) => a + g.violations_total, 0)} violation(s)` : ""}${fixes.length ? `; would fix it: ${fixes.join("; ")}` : ""}`;
    return li;
  }

  _card(f, k) {
    const st = this.state;
    const li = document.createElement("li");
    li.className = "tl-card";
    li.draggable = true;
    li.dataset.index = String(k);
    li.setAttribute("aria-label", `Formation ${k + 1}: ${f.name}`);
    if (k === st.current) li.setAttribute("aria-current", "true");
    const problem = this.problems.get(k);
    if (problem) li.classList.add("has-problem");

    const name = document.createElement("input");
    name.className = "tl-name";
    name.value = f.name;
    name.maxLength = 200;
    name.setAttribute("aria-label", `Name of formation ${k + 1}`);
    // Edits wait for the focus move that committed them (Tab fires change before the focus
    // moves): the rebuild then puts focus back on the rebuilt control the user tabbed to.
    name.addEventListener("change", () => setTimeout(() => {
      const v = name.value.trim();
      if (!v) { name.value = f.name; return; }
      st.edit("Rename formation", () => { st.show.formations[k].name = v; });
    }));

    const meta = document.createElement("div");
    meta.className = "tl-meta";
    const holdLabel = document.createElement("label");
    holdLabel.textContent = "hold";
    const hold = document.createElement("input");
    hold.type = "number";
    // Steps count from min: with min 0 the arrows move by whole half seconds (5 -> 4.5, not 4.6); a hold of 0
    // is refused below (the show file needs > 0).
    hold.min = "0";
    hold.step = "0.5";
    hold.value = String(f.hold_s);
    hold.setAttribute("aria-label", `Hold time of formation ${k + 1}, seconds`);
    if (f.leave_at_s != null) {
      // A departure pin (issue 18) sets the hold's end: hold_s is not used.
      hold.disabled = true;
      hold.title = `The hold lasts until the departure pin at ${f.leave_at_s} s`;
    }
    hold.addEventListener("change", () => setTimeout(() => {
      const v = hold.value.trim() === "" ? NaN : Number(hold.value);
      const problem = durationProblem(v);
      if (problem) {
        // Refused here, with the reason (it used to be put back silently, or saved as a draft above 24 hours).
        hold.value = String(f.hold_s);
        toast(`Hold of "${f.name}" ${problem}; kept ${f.hold_s} s`, { error: true });
        return;
      }
      st.edit("Change hold time", () => { st.show.formations[k].hold_s = v; });
    }));
    holdLabel.append(" ", hold, " s");
    const count = document.createElement("span");
    const n = f.points.length;
    count.textContent = `${n} pts`;
    const flying = flyingCount(st.show, f);  // a subset formation (issue 21) needs points for its drones only
    if (n < flying) {
      count.className = "bad-value";
      count.title = `${flying - n} fewer points than drones: use "Fit to N drones"`;
    }
    if (flying < st.show.drones) count.textContent += ` · ${flying} drones`;
    meta.append(holdLabel, count);
    if (f.arrive_at_s != null || f.leave_at_s != null) {
      // Cue times (issue 18): pinned on the music lane.
      const pin = document.createElement("span");
      pin.className = "tl-pin";
      pin.textContent = `⟂ ${f.arrive_at_s != null ? f.arrive_at_s.toFixed(2) : "…"}${f.leave_at_s != null ? `–${f.leave_at_s.toFixed(2)}` : ""} s`;
      pin.title = "Pinned cue time (drag its marker on the music lane; double-click it to unpin)";
      meta.append(pin);
    }

    const sw = document.createElement("div");
    sw.className = "tl-swatches";
    const cols = formationColors(f);
    const stops = [0, 0.25, 0.5, 0.75, 1].map((t) => cols[Math.min(cols.length - 1, Math.floor(t * (cols.length - 1)))] || "#fff");
    sw.style.background = `linear-gradient(90deg, ${stops.join(", ")})`;

    li.append(name, meta, sw);
    if (problem) {
      const err = document.createElement("p");
      err.className = "field-error";
      err.setAttribute("role", "alert");
      err.textContent = problem;
      err.title = problem;
      li.append(err);
    }
    li.addEventListener("click", (e) => {
      // Anywhere on the card but its own controls (the problem text too) selects the formation.
      const t = /** @type {HTMLElement} */ (e.target);
      if (!t.closest("input, button, select, textarea")) st.setCurrent(k);
    });
    li.addEventListener("focusin", () => { if (st.current !== k) st.setCurrent(k); });
    li.addEventListener("dragstart", (e) => {
      this._dragFrom = k;
      e.dataTransfer.effectAllowed = "move";
      e.dataTransfer.setData("text/plain", String(k));
    });
    li.addEventListener("dragover", (e) => {
      if (this._dragFrom < 0) return;
      e.preventDefault();
      li.classList.add("drag-over");
    });
    li.addEventListener("dragleave", () => li.classList.remove("drag-over"));
    li.addEventListener("drop", (e) => {
      e.preventDefault();
      li.classList.remove("drag-over");
      const from = this._dragFrom;
      this._dragFrom = -1;
      this.move(from, k);
    });
    li.addEventListener("dragend", () => { this._dragFrom = -1; });
    return li;
  }
}
