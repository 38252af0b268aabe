// @ts-check
// "Check": plan and verify the stored show, show the report; clicking a violation selects the
// formation and the drones involved.

import * as api from "./api.js";
import { clearShowErrors, showShowErrors } from "./errors.js";
import { closestText, distanceForOrder, fmt, limitRow, plannerText, summaryTable } from "./summary.js";

/** @type {[string, string, string, string, "min"|"max", string?][]} label, report key, limit key, unit, sense,
 * the text when the report has no value (null: a one-drone show has no pair) */
const LIMIT_ROWS = [
  ["Minimum distance", "min_distance_m", "min_distance_m", "m", "min", "none (one drone, no pair)"],
  ["Peak horizontal speed", "max_speed_xy_mps", "max_speed_xy_mps", "m/s", "max"],
  ["Peak vertical speed", "max_speed_z_mps", "max_speed_z_mps", "m/s", "max"],
  ["Peak acceleration", "max_accel_mps2", "max_accel_mps2", "m/s²", "max"],
  ["Highest altitude", "max_altitude_m", "max_altitude_m", "m", "max"],
];

const KIND_NAMES = {
  min_distance: "Too close",
  speed_xy: "Horizontal speed",
  speed_z: "Vertical speed",
  acceleration: "Acceleration",
  altitude: "Altitude",
  min_altitude: "Below the altitude floor",
  geofence: "Outside the geofence",
  transition_duration: "Transition too short",
  downwash: "In downwash (ellipsoid units, < 1 inside)",
};

/**
 * Formation index a plan segment belongs to: takeoff -> the first, a transition -> its destination,
 * a hold -> its formation, landing -> the last.
 * @param {{index: number, kind: string}[]} segments
 * @param {number} segment
 * @param {number} count number of formations
 * @returns {number}
 */
export function formationOfSegment(segments, segment, count) {
  const seg = segments.find((s) => s.index === segment);
  if (!seg || seg.kind === "takeoff") return 0;
  if (seg.kind === "landing") return count - 1;
  const holdsBefore = segments.filter((s) => s.kind === "hold" && s.index < segment).length;
  return Math.min(count - 1, seg.kind === "hold" ? holdsBefore : holdsBefore);
}

/**
 * Groups of the check, failing first, then by smallest minimum distance (the CLI's order).
 * @param {any[]} groups
 * @returns {any[]}
 */
export function worstFirst(groups) {
  const d = (g) => distanceForOrder(g.min_distance_m);
  return [...groups].sort((a, b) => (a.ok - b.ok) || (d(a) - d(b)) || (a.segment - b.segment));
}

const GROUP_KINDS = { takeoff: "Takeoff", transition: "Transition", landing: "Landing", hold: "Hold" };

/** Takeoff and landing say where they go ("Landing landing → home" said it twice). */
const END_WHAT = { takeoff: "from the homes", landing: "onto the homes" };

/**
 * One line naming a group: its kind, ends, length, stagger and outcome.
 * @param {any} g a group of the check report's `by_transition`
 * @returns {string}
 */
export function groupTitle(g) {
  const what = g.kind === "hold" ? g.to : END_WHAT[g.kind] || `${g.from} → ${g.to}`;
  const timing = `${fmt(g.duration_s, 1)} s${g.stagger_s > 0 ? ` (+${fmt(g.stagger_s, 1)} s stagger)` : ""}`;
  const closest = closestText(g.min_distance_m);
  const outcome = g.ok ? "✓" : `✗ ${g.violations_total} violation${g.violations_total === 1 ? "" : "s"}`;
  return `${outcome} · ${GROUP_KINDS[g.kind] || g.kind} ${what} · ${timing}${closest}`;
}

/** The unit of a violation's value and limit (sim.verify.Violation: metres, m/s, m/s²; downwash in ellipsoid units). */
const KIND_UNITS = {
  speed_xy: " m/s",
  speed_z: " m/s",
  acceleration: " m/s²",
  altitude: " m",
  min_altitude: " m",
  geofence: " m",
};

/**
 * A violation as a short line (the report's message is the tooltip).
 * @param {{kind: string, drones: number[], value: number, limit: number, time_s: number}} v
 * @returns {string}
 */
export function violationText(v) {
  if (v.kind === "min_distance") return `Drones ${v.drones[0]} & ${v.drones[1]}: ${fmt(v.value)} m at ${fmt(v.time_s, 1)} s`;
  if (v.kind === "transition_duration") return `Too short: ${fmt(v.value, 1)} s, needs ${fmt(v.limit, 1)} s`;
  const unit = KIND_UNITS[v.kind] || "";
  const more = v.drones.length > 5 ? ", …" : "";
  return `${KIND_NAMES[v.kind] || v.kind}: ${fmt(v.value)}${unit} (limit ${fmt(v.limit)}${unit}) at ${fmt(v.time_s, 1)} s, drone${v.drones.length === 1 ? "" : "s"} ${v.drones.slice(0, 5).join(", ")}${more}`;
}

/** The check panel. */
export class ReportPanel {
  /**
   * @param {HTMLElement} body
   * @param {import("./state.js").EditorState} state
   * @param {import("./persist.js").Persistence} persist
   * @param {{timeline: import("./timeline.js").Timeline, view: import("./canvas.js").CanvasView}} parts
   */
  constructor(body, state, persist, parts) {
    this.body = body;
    this.state = state;
    this.persist = persist;
    this.parts = parts;
    this.result = null;
    this.checkedVersion = -1;
    state.addEventListener("change", (/** @type {CustomEvent} */ e) => {
      if (e.detail.kind === "load") this.clear();
      if (e.detail.kind === "edit" && this.result) this.body.querySelector(".stale")?.removeAttribute("hidden");
    });
  }

  /** Forget the last report. */
  clear() {
    this.result = null;
    this.parts.view.flagged = new Set();
    this.body.innerHTML = '<p class="muted">Press Check to plan the show and verify separation, speeds and altitude.</p>';
  }

  /** Save if needed, then plan and verify the show. */
  async run() {
    const st = this.state;
    if (!st.meta) return;
    const btn = /** @type {HTMLButtonElement} */ (document.getElementById("btn-check"));
    btn.disabled = true;
    btn.setAttribute("aria-busy", "true");
    this.body.innerHTML = '<p class="muted" role="status">Checking…</p>';
    try {
      if (!(await this.persist.ensureSaved())) {
        this.body.innerHTML = "";
        this.body.append(this._p("report-bad", "Not checked: the show could not be saved (see the message at the top)."));
        return;
      }
      const draft = this.persist.draftRefusal("checked");
      if (draft) {
        this.body.innerHTML = "";
        this.body.append(this._p("report-bad", draft));
        return;
      }
      const res = await api.checkShow(st.meta.id);
      this.result = res;
      this.checkedVersion = st.version;
      clearShowErrors();
      this.render();
    } catch (err) {
      this.body.innerHTML = "";
      this.body.append(this._p("report-bad", `Not checked: ${err.message}`));
      if (err instanceof api.ApiError && err.status === 422) {
        showShowErrors(err.problems, () => {});
        this.parts.timeline.render();
      }
    } finally {
      btn.disabled = false;
      btn.removeAttribute("aria-busy");
    }
  }

  _p(cls, text) {
    const p = document.createElement("p");
    p.className = cls;
    p.textContent = text;
    return p;
  }

  /** Draw the report of the last check. */
  render() {
    const res = this.result;
    if (!res) return;
    const r = res.report;
    const segments = (res.plan && res.plan.segments) || [];
    const count = this.state.show.formations.length;
    this.body.replaceChildren();
    const [head, table] = summaryTable(r.ok, r.ok ? "✓ Safe: every limit holds" : `✗ ${r.violations_total} violation${r.violations_total === 1 ? "" : "s"}`,
      "Check summary", [
        ["Duration", `${fmt(r.duration_s, 1)} s`],
        ...LIMIT_ROWS.map(([label, key, limitKey, unit, sense, none]) =>
          limitRow(label, r[key], r.limits ? r.limits[limitKey] : undefined, unit, sense, none)),
        r.min_distance_pair && r.min_distance_pair.length === 2
          && ["Closest pair", `drones ${r.min_distance_pair[0]} & ${r.min_distance_pair[1]} at ${fmt(r.min_distance_time_s, 1)} s`],
      ]);
    const stale = this._p("muted stale", "The show changed since this check.");
    stale.hidden = this.checkedVersion === this.state.version;
    this.body.append(head, stale, table);

    // Per-transition timing (length, stagger, whether it is safe) on the timeline.
    const groups = Array.isArray(r.by_transition) ? r.by_transition : [];
    const tl = this.parts.timeline;
    tl.setCheck(this.state.show.formations.length, groups, r.transitions || []);
    tl.render();

    if (groups.length) this.body.append(this._groups(groups, segments, count));
    else if (r.violations && r.violations.length) this.body.append(this._violationList(r.violations, segments, count));
  }

  /**
   * The violations grouped per transition, worst first (failing first, smallest distance first),
   * each group collapsible; a failing group lists what would fix it.
   * @param {any[]} groups `by_transition` of the report
   * @param {any[]} segments plan segments
   * @param {number} count number of formations
   */
  _groups(groups, segments, count) {
    const wrap = document.createElement("section");
    wrap.className = "report-groups";
    wrap.setAttribute("aria-label", "Check per transition, worst first");
    const h = document.createElement("h3");
    h.textContent = "Per transition (worst first)";
    wrap.append(h);
    let firstBad = true;
    for (const g of worstFirst(groups)) {
      const det = document.createElement("details");
      det.className = `report-group ${g.ok ? "group-ok" : "group-bad"}`;
      det.dataset.segment = String(g.segment);
      if (!g.ok && firstBad) {
        det.open = true;
        firstBad = false;
      }
      const sum = document.createElement("summary");
      sum.textContent = groupTitle(g);
      det.append(sum);
      if (g.stagger_s > 0 || g.resolution) {
        det.append(this._p("muted", [plannerText(g.resolution), g.stagger_s > 0 ? `Stagger added: ${fmt(g.stagger_s, 1)} s.` : ""]
          .filter(Boolean).join(" ")));
      }
      if (!g.ok) {
        det.append(this._fixes(g));
        if (g.violations.length) det.append(this._violationList(g.violations, segments, count));
        if (g.violations_total > g.violations.length) det.append(this._p("muted", `… and ${g.violations_total - g.violations.length} more in this transition.`));
      }
      wrap.append(det);
    }
    return wrap;
  }

  /**
   * What would fix a failing group: the planner's own fixes (text), and a button only for the
   * fixes the editor can apply and that change the outcome: letting the planner choose a duration
   * the designer forced, or repairing a formation's spacing. A longer duration is never offered for
   * drones that come too close: the planner's lines do not depend on it.
   * @param {any} g
   */
  _fixes(g) {
    const box = document.createElement("div");
    box.className = "group-fixes";
    const texts = (g.fixes || []).filter((f) => f);
    if (texts.length) {
      const h = document.createElement("p");
      h.className = "fix-head";
      h.textContent = "What would fix it:";
      const ul = document.createElement("ul");
      ul.className = "fix-list";
      for (const t of texts) {
        const li = document.createElement("li");
        li.textContent = t;
        ul.append(li);
      }
      box.append(h, ul);
    } else {
      box.append(this._p("muted", "The planner gave no fix for this transition."));
    }
    const f = g.formation >= 0 ? this.state.show.formations[g.formation] : null;
    const kinds = new Set((g.violations || []).map((v) => v.kind));
    const tooFast = kinds.has("transition_duration") || kinds.has("speed_xy") || kinds.has("speed_z") || kinds.has("acceleration");
    if (f && g.kind === "transition" && f.transition_s != null && tooFast) {
      const b = document.createElement("button");
      b.type = "button";
      b.textContent = "Let the planner choose this duration";
      b.setAttribute("aria-label", `Let the planner choose the duration of the transition into "${f.name}"`);
      b.addEventListener("click", () => this.parts.timeline.setTransition(g.formation, null));
      box.append(b);
    }
    if (f && g.kind === "hold" && kinds.has("min_distance")) {
      const b = document.createElement("button");
      b.type = "button";
      b.textContent = `Repair spacing of "${f.name}"`;
      b.setAttribute("aria-label", `Repair the spacing of formation "${f.name}"`);
      b.addEventListener("click", () => {
        this.state.setCurrent(g.formation);
        document.getElementById("btn-repair")?.click();
      });
      box.append(b);
    }
    return box;
  }

  /**
   * A list of violations; clicking one selects its formation and drones.
   * @param {any[]} violations
   * @param {any[]} segments
   * @param {number} count
   */
  _violationList(violations, segments, count) {
    const ul = document.createElement("ul");
    ul.className = "violations";
    ul.setAttribute("aria-label", "Violations (click to select the drones)");
    for (const v of violations) {
      const li = document.createElement("li");
      const b = document.createElement("button");
      b.type = "button";
      const k = formationOfSegment(segments, v.segment, count);
      const fname = this.state.show.formations[k]?.name ?? "";
      b.textContent = violationText(v);
      // A transition that is too short names no drones: the button then selects the formation only.
      const who = v.drones.length ? ` and drones ${v.drones.join(", ")}` : "";
      b.title = `${v.message || ""}\nSelect formation "${fname}"${who}`;
      b.setAttribute("aria-label", v.drones.length
        ? `${KIND_NAMES[v.kind] || v.kind} at ${fmt(v.time_s, 1)} s, drones ${v.drones.join(", ")}: select them in "${fname}"`
        : `${KIND_NAMES[v.kind] || v.kind} at ${fmt(v.time_s, 1)} s: select "${fname}"`);
      b.addEventListener("click", () => this.select(v, k));
      li.append(b);
      ul.append(li);
    }
    return ul;
  }

  /**
   * Select a violation's formation and its drones' points: the targets of those drones in that
   * formation (`points` in the report; without it only the formation is selected).
   * @param {any} v violation
   * @param {number} k formation index
   */
  select(v, k) {
    const st = this.state;
    st.setCurrent(k);
    const f = st.formation;
    const idx = (Array.isArray(v.points) ? v.points : []).filter((i) => i >= 0 && i < f.points.length);
    this.parts.view.flagged = new Set(idx);
    st.setSelection(idx);
    this.parts.view.fit();
  }
}
