// Revision history: the stored revisions of the open show (GET /api/shows/{id}/revisions), what
// each changed compared with the document being edited, and restoring one as an undoable edit.

import * as api from "./api.js";
import { setError } from "./errors.js";
import { DEFAULT_SETTINGS, withColors } from "./state.js";

/**
 * What differs between two show documents, in a few words per part.
 * @param {any} from the revision's show
 * @param {any} to the document being edited
 * @returns {string[]} one line per difference (empty: the same)
 */
export function diffSummary(from, to) {
  const out = [];
  if (from.name !== to.name) out.push(`name "${from.name}" → "${to.name}"`);
  if (from.drones !== to.drones) out.push(`drones ${from.drones} → ${to.drones}`);
  const a = from.settings || {};
  const b = to.settings || {};
  const keys = [...new Set([...Object.keys(a), ...Object.keys(b)])].filter((k) => JSON.stringify(a[k]) !== JSON.stringify(b[k]));
  if (keys.length) out.push(`settings: ${keys.join(", ")}`);
  if (JSON.stringify(from.home) !== JSON.stringify(to.home)) out.push("home positions");
  const fa = from.formations || [];
  const fb = to.formations || [];
  const namesA = fa.map((f) => f.name);
  const namesB = fb.map((f) => f.name);
  const added = namesB.filter((n) => !namesA.includes(n));
  const removed = namesA.filter((n) => !namesB.includes(n));
  if (added.length) out.push(`added ${added.map((n) => `"${n}"`).join(", ")}`);
  if (removed.length) out.push(`removed ${removed.map((n) => `"${n}"`).join(", ")}`);
  const changed = [];
  for (const f of fb) {
    const g = fa.find((x) => x.name === f.name);
    if (!g) continue;
    const parts = [];
    if (JSON.stringify(g.points) !== JSON.stringify(f.points)) parts.push(g.points.length === f.points.length ? "points" : `${g.points.length} → ${f.points.length} points`);
    if (JSON.stringify(withColors(g).colors) !== JSON.stringify(withColors(f).colors)) parts.push("colours");
    if (g.hold_s !== f.hold_s) parts.push(`hold ${g.hold_s} → ${f.hold_s} s`);
    if (g.transition_s !== f.transition_s) parts.push("transition");
    if (parts.length) changed.push(`"${f.name}": ${parts.join(", ")}`);
  }
  if (changed.length) out.push(...changed);
  const common = namesB.filter((n) => namesA.includes(n));
  const orderA = namesA.filter((n) => common.includes(n));
  if (!added.length && !removed.length && JSON.stringify(orderA) !== JSON.stringify(common)) out.push("formation order");
  return out;
}

/** The revision history panel. */
export class HistoryPanel {
  /**
   * @param {HTMLElement} body where the list goes
   * @param {import("./state.js").EditorState} state
   */
  constructor(body, state) {
    this.body = body;
    this.state = state;
    const details = /** @type {HTMLDetailsElement} */ (document.getElementById("history-panel"));
    details.addEventListener("toggle", () => { if (details.open) this.refresh(); });
    document.getElementById("btn-history-refresh").addEventListener("click", () => this.refresh());
    state.addEventListener("change", (e) => {
      if ((e.detail.kind === "load" || e.detail.kind === "saved") && details.open) this.refresh();
    });
  }

  /** List the revisions, newest first. */
  async refresh() {
    setError("history", "");
    const st = this.state;
    this.body.replaceChildren();
    if (!st.meta) return;
    let list;
    try {
      list = await api.request("GET", `/api/shows/${encodeURIComponent(st.meta.id)}/revisions?limit=50`);
    } catch (err) {
      setError("history", `Cannot list the revisions: ${err.message}`);
      return;
    }
    const ul = document.createElement("ul");
    ul.className = "revisions";
    ul.setAttribute("aria-label", "Revisions");
    for (const r of list.items) {
      const li = document.createElement("li");
      const head = document.createElement("span");
      head.textContent = `r${r.revision} · ${new Date(r.created_at).toLocaleString()} · ${r.drones} drones, ${r.formations} formations${r.draft ? " · draft" : ""}${r.revision === st.meta.revision ? " (open)" : ""}`;
      li.append(head);
      if (r.has_show) {
        const diff = document.createElement("button");
        diff.type = "button";
        diff.textContent = "Changes";
        diff.setAttribute("aria-label", `What changed since revision ${r.revision}`);
        const restore = document.createElement("button");
        restore.type = "button";
        restore.textContent = "Restore";
        restore.setAttribute("aria-label", `Restore revision ${r.revision}`);
        const out = document.createElement("p");
        out.className = "muted revision-diff";
        diff.addEventListener("click", async () => {
          const doc = await this._fetch(r.revision);
          if (!doc) return;
          const lines = diffSummary(doc, this.state.show);
          out.textContent = lines.length ? `Since r${r.revision}: ${lines.join("; ")}` : `The same as r${r.revision}.`;
        });
        restore.addEventListener("click", () => this.restore(r.revision));
        li.append(" ", diff, " ", restore, out);
      } else {
        li.append(" (pruned: only its summary is kept)");
      }
      ul.append(li);
    }
    this.body.append(ul);
  }

  async _fetch(revision) {
    try {
      return await api.request("GET", `/api/shows/${encodeURIComponent(this.state.meta.id)}/revisions/${revision}`);
    } catch (err) {
      setError("history", `Cannot read revision ${revision}: ${err.message}`);
      return null;
    }
  }

  /**
   * Replace the document with a stored revision (one undo step; saving makes it the newest revision).
   * @param {number} revision
   */
  async restore(revision) {
    const doc = await this._fetch(revision);
    const st = this.state;
    if (!doc || !st.show) return;
    st.edit(`Restore revision ${revision}`, () => {
      // As EditorState.load reads a document: defaults under its settings, one colour per point.
      for (const k of Object.keys(st.show)) delete st.show[k];
      Object.assign(st.show, structuredClone(doc));
      st.show.settings = { ...DEFAULT_SETTINGS, ...(doc.settings || {}) };
      st.show.formations = st.show.formations.map(withColors);
      st.current = Math.min(st.current, st.show.formations.length - 1);
      st.selection = new Set();
    });
  }
}
