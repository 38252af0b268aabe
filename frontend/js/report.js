// "Check": plan and verify the stored show, show the report; clicking a violation selects the
// formation and the drones involved.

import * as api from "./api.js";
import { clearShowErrors, showShowErrors } from "./errors.js";

const LIMIT_ROWS = [
  ["Minimum distance", "min_distance_m", "min_distance_m", "m", "min"],
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
  transition_duration: "Transition too short",
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

function fmt(v, digits = 2) {
  return v == null || !Number.isFinite(v) ? "—" : Number(v).toFixed(digits);
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
    state.addEventListener("change", (e) => {
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
    const btn = document.getElementById("btn-check");
    btn.disabled = true;
    btn.setAttribute("aria-busy", "true");
    this.body.innerHTML = '<p class="muted" role="status">Checking…</p>';
    try {
      if (!(await this.persist.ensureSaved())) {
        this.body.innerHTML = "";
        this.body.append(this._p("report-bad", "Not checked: the show could not be saved (see the message at the top)."));
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
    this.body.append(this._p(r.ok ? "report-ok" : "report-bad", r.ok ? "✓ Safe: every limit holds" : `✗ ${r.violations_total} violation${r.violations_total === 1 ? "" : "s"}`));
    const stale = this._p("muted stale", "The show changed since this check.");
    stale.hidden = this.checkedVersion === this.state.version;
    this.body.append(stale);

    const table = document.createElement("table");
    table.setAttribute("aria-label", "Check summary");
    const row = (label, value, bad) => {
      const tr = document.createElement("tr");
      const a = document.createElement("td");
      a.textContent = label;
      const b = document.createElement("td");
      b.textContent = value;
      if (bad) b.className = "bad-value";
      tr.append(a, b);
      table.append(tr);
    };
    row("Duration", `${fmt(r.duration_s, 1)} s`);
    for (const [label, key, limitKey, unit, sense] of LIMIT_ROWS) {
      const v = r[key];
      const lim = r.limits ? r.limits[limitKey] : undefined;
      const bad = lim != null && v != null && (sense === "min" ? v < lim - 1e-9 : v > lim + 1e-9);
      row(label, `${fmt(v)} ${unit}${lim != null ? ` (${sense === "min" ? "≥" : "≤"} ${fmt(lim, 1)})` : ""}`, bad);
    }
    if (r.min_distance_pair && r.min_distance_pair.length === 2) {
      row("Closest pair", `drones ${r.min_distance_pair[0]} & ${r.min_distance_pair[1]} at ${fmt(r.min_distance_time_s, 1)} s`);
    }
    this.body.append(table);

    // Planned transition durations on the timeline.
    const tl = this.parts.timeline;
    tl.transitions = this.state.show.formations.map((_, k) => {
      const t = (r.transitions || [])[k];
      return t ? t.duration_s : null;
    });
    tl.minDurations = this.state.show.formations.map((_, k) => {
      const t = (r.transitions || [])[k];
      return t ? t.min_duration_s : null;
    });
    tl.render();

    if (r.violations && r.violations.length) {
      const h = document.createElement("h3");
      h.textContent = "Violations (click to select)";
      const ul = document.createElement("ul");
      ul.className = "violations";
      ul.setAttribute("aria-label", "Violations");
      for (const v of r.violations) {
        const li = document.createElement("li");
        const b = document.createElement("button");
        b.type = "button";
        const k = formationOfSegment(segments, v.segment, count);
        const fname = this.state.show.formations[k]?.name ?? "";
        b.textContent = v.message || `${KIND_NAMES[v.kind] || v.kind}: drones ${v.drones.join(", ")} at ${fmt(v.time_s, 1)} s: ${fmt(v.value)} (limit ${fmt(v.limit)})`;
        b.title = `Select formation "${fname}" and drones ${v.drones.join(", ")}`;
        b.setAttribute("aria-label", `${KIND_NAMES[v.kind] || v.kind} at ${fmt(v.time_s, 1)} s, drones ${v.drones.join(", ")}: select them in "${fname}"`);
        b.addEventListener("click", () => this.select(v, k));
        li.append(b);
        ul.append(li);
      }
      this.body.append(h, ul);
      if (r.violations_total > r.violations.length) this.body.append(this._p("muted", `… and ${r.violations_total - r.violations.length} more.`));
    }
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
