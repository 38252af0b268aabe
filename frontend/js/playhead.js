// @ts-check
// One playhead for the timeline and this tab's 3D preview: selecting a formation seeks the preview to
// its hold, the preview's time shows on the timeline while it plays, and the transitions with
// problems (from the last check) are markers above the cards, worst first; a marker selects its
// formation and seeks the preview to its worst violation.

import * as api from "./api.js";
import { distanceForOrder } from "./summary.js";

/** How often the preview's playhead is read, milliseconds. */
const POLL_MS = 200;

/**
 * Checks worst first: failing ones only, smallest minimum distance first (no distance: last), then in show order.
 * @param {any[]} groups `by_transition` entries
 * @returns {any[]}
 */
export function worstFirst(groups) {
  const d = (/** @type {any} */ g) => distanceForOrder(g.min_distance_m);
  return groups.filter((g) => g && !g.ok).sort((a, b) => d(a) - d(b) || a.segment - b.segment);
}

/** Shares the playhead between the timeline and the preview of this tab. */
export class Playhead {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {import("./timeline.js").Timeline} timeline
   * @param {import("./preview.js").Preview} preview
   */
  constructor(state, timeline, preview) {
    this.state = state;
    this.timeline = timeline;
    this.preview = preview;
    /** @type {number|null} a time to seek to instead of the next selected formation's hold */
    this._pendingTime = null;
    const list = timeline.list;
    this.strip = document.createElement("div");
    this.strip.id = "tl-problems";
    this.strip.className = "tl-problems";
    this.strip.setAttribute("role", "toolbar");
    this.strip.setAttribute("aria-label", "Transitions with problems, worst first");
    this.strip.hidden = true;
    list.before(this.strip);
    this.readout = document.createElement("span");
    this.readout.id = "tl-playhead";
    this.readout.className = "muted";
    this.readout.setAttribute("aria-live", "off");
    const head = list.parentElement && list.parentElement.querySelector(".timeline-head");
    (head || list.parentElement || document.body).append(this.readout);
    // The timeline rebuilds its cards after every edit and check: redraw the markers and the playhead then.
    new MutationObserver(() => {
      this.renderProblems();
      this._mark(this.preview.viewerState());
    }).observe(list, { childList: true });
    state.addEventListener("change", (/** @type {CustomEvent} */ e) => {
      if (e.detail.kind === "current") this._onCurrent();
    });
    /** @type {string|null} the preview page last seen (a new one may have to start at the selected formation) */
    this._page = null;
    this._timer = setInterval(() => this._poll(), POLL_MS);
  }

  /** Redraw the problem markers from the timeline's last check. */
  renderProblems() {
    const tl = this.timeline;
    const groups = worstFirst([...tl.checks, ...tl.ends]);
    this.strip.replaceChildren();
    this.strip.hidden = groups.length === 0;
    for (const g of groups) {
      const worst = (g.violations || [])[0];
      const b = document.createElement("button");
      b.type = "button";
      b.className = "tl-problem";
      const where = g.kind === "transition" ? `${g.from} → ${g.to}` : g.kind;
      b.textContent = `⚠ ${where}: ${g.violations_total}`;
      b.title = worst ? `${worst.message}${g.fixes && g.fixes.length ? `. Would fix it: ${g.fixes.join("; ")}` : ""}` : "";
      b.setAttribute("aria-label", `Problem: ${where}, ${g.violations_total} violation(s); select it and show it in the 3D view`);
      b.addEventListener("click", () => this.showProblem(g));
      this.strip.append(b);
    }
  }

  /**
   * Select the formation a checked segment leads into and seek the preview to its worst violation.
   * @param {any} g a `by_transition` entry
   */
  showProblem(g) {
    const worst = (g.violations || [])[0];
    const t = worst ? worst.time_s : g.start_s;
    const st = this.state;
    if (g.formation >= 0 && g.formation !== st.current) {
      this._pendingTime = t;
      st.setCurrent(g.formation);
    } else {
      this.seek({ time_s: t });
    }
  }

  /**
   * Move this tab's preview playback (nothing when the preview is closed).
   * @param {{time_s?: number, formation?: number}} where
   */
  async seek(where) {
    const vs = this.preview.viewerState();
    if (!vs) return;
    try {
      await api.viewerSeek(vs.token, where);
    } catch {
      // The preview page went away or shows another show: the next poll shows where it is.
    }
  }

  _onCurrent() {
    const t = this._pendingTime;
    this._pendingTime = null;
    if (t != null) this.seek({ time_s: t });
    else this.seek({ formation: this.state.current });
  }

  _poll() {
    const vs = this.preview.viewerState();
    if (vs && vs.token !== this._page) {
      this._page = vs.token;
      const k = this.preview.startFormation;
      const t = this.preview.startTime;
      this.preview.startFormation = this.preview.startTime = null;
      if (t != null) this.seek({ time_s: t });
      else if (k != null && k > 0) this.seek({ formation: k });
    }
    this.readout.textContent = vs ? `3D ${vs.playing ? "▶" : "‖"} ${vs.time_s.toFixed(1)} s` : "";
    this._mark(vs);
  }

  /**
   * Mark the card (hold) or transition the preview's playhead is in.
   * @param {ReturnType<import("./preview.js").Preview["viewerState"]>} vs
   */
  _mark(vs) {
    const list = this.timeline.list;
    const cards = list.querySelectorAll(".tl-card");
    const moves = list.querySelectorAll(".tl-transition");
    /** @type {Element|null} */
    let at = null;
    if (vs && vs.formation >= 0) at = (vs.phase === "hold" ? cards : moves)[vs.formation] || null;
    for (const el of list.querySelectorAll(".playhead")) if (el !== at) el.classList.remove("playhead");
    if (at) at.classList.add("playhead");
  }
}
