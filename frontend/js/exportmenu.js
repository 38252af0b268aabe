// @ts-check
// The export menu: every format the backend offers, downloaded through
// GET /api/shows/{id}/export/{format}; errors appear next to the menu.

import * as api from "./api.js";
import { toast } from "./dialogs.js";
import { showShowErrors } from "./errors.js";
import { exportProblem, exportQuery, parseOrigin } from "./exportcheck.js";
import { downloadBlob } from "./shows.js";

/** Human names of the known formats. */
export const FORMAT_LABELS = {
  show: "Show file (.json)",
  "skybrush-csv": "Skybrush CSV (.zip)",
  skyc: "Skybrush Live (.skyc)",
  crazyswarm: "Crazyswarm polynomials (.zip)",
  "qgc-plan": "QGroundControl .plan (.zip)",
  "qgc-wpl": "QGC WPL 110 (.zip)",
  "waypoints-csv": "Waypoints CSV (.zip)",
  "viser-html": "3D playback (.html)",
};

/** The export select and button. */
export class ExportMenu {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {import("./persist.js").Persistence} persist
   * @param {{onFormationProblems?: () => void}} [hooks] onFormationProblems: a refusal named formations
   *   (marked in `formationProblems`): the timeline redraws its cards
   */
  constructor(state, persist, hooks = {}) {
    this.state = state;
    this.persist = persist;
    this.hooks = hooks;
    this.select = /** @type {HTMLSelectElement} */ (document.getElementById("export-format"));
    this.button = /** @type {HTMLButtonElement} */ (document.getElementById("btn-export"));
    this.button.addEventListener("click", () => this.run());
    this.select.addEventListener("change", () => this._clearErrors());
    this.fields = {
      origin: /** @type {HTMLInputElement} */ (document.getElementById("exp-origin")),
      heading_deg: /** @type {HTMLInputElement} */ (document.getElementById("exp-heading")),
      fps: /** @type {HTMLInputElement} */ (document.getElementById("exp-fps")),
      source: /** @type {HTMLSelectElement} */ (document.getElementById("exp-source")),
      scale: /** @type {HTMLInputElement} */ (document.getElementById("exp-scale")),
      offset: /** @type {HTMLInputElement} */ (document.getElementById("exp-offset")),
    };
    for (const [key, el] of Object.entries(this.fields)) {
      // The place on Earth belongs to the show (settings.geo); rate and source are the browser's.
      if (key === "origin" || key === "heading_deg") {
        el.addEventListener("change", () => this._setGeo());
        continue;
      }
      const saved = localStorage.getItem(`swarmshow.export.${key}`);
      if (saved !== null) el.value = saved;
      el.addEventListener("change", () => localStorage.setItem(`swarmshow.export.${key}`, el.value));
    }
    state.addEventListener("change", (/** @type {CustomEvent} */ e) => {
      if (e.detail.kind === "load" || e.detail.kind === "edit") this._showGeo();
    });
  }

  /** Clear the last export's refusal (beside the menu and, for a missing origin, under the origin field). */
  _clearErrors() {
    document.getElementById("export-error").textContent = "";
    document.querySelector('[data-error-for="origin"]').textContent = "";
  }

  /** Fill the origin and heading fields from the show's `settings.geo`. */
  _showGeo() {
    const geo = this.state.show && this.state.show.settings.geo;
    this.fields.origin.value = geo ? `${geo.origin_lat_deg}, ${geo.origin_lon_deg}, ${geo.origin_alt_m}` : "";
    this.fields.heading_deg.value = geo ? String(geo.heading_deg) : "0";
  }

  /** Store the typed origin and heading in the show (one undo step); blank origin removes them. */
  _setGeo() {
    const st = this.state;
    const err = document.querySelector('[data-error-for="origin"]');
    err.textContent = "";
    if (!st.show) return;
    const text = this.fields.origin.value.trim();
    const heading = Number(this.fields.heading_deg.value || 0);
    if (!text) {
      if (st.show.settings.geo) st.edit("Remove the show's origin", () => { delete st.show.settings.geo; });
      return;
    }
    // The show file's bounds (settings.geo), so that a typed origin is never refused later by the save.
    const { value: v, error } = parseOrigin(text);
    if (!v) {
      err.textContent = error;
      return;
    }
    // As the API and the command line: within one turn either way (400 is a typo for 40, not a bearing).
    if (!Number.isFinite(heading) || Math.abs(heading) > 360) {
      err.textContent = "Heading: degrees clockwise from north, between -360 and 360";
      return;
    }
    const geo = { origin_lat_deg: v[0], origin_lon_deg: v[1], origin_alt_m: v[2], heading_deg: ((heading % 360) + 360) % 360 };
    st.edit("Set the show's origin", () => { st.show.settings.geo = geo; });
  }

  /**
   * The export options of `format` as query parameters: only those the format takes (exportQuery), with the
   * simulation panel's preset and seed for the flown trajectories.
   * @param {string} format
   * @returns {Record<string, string>}
   */
  options(format) {
    const value = (/** @type {string} */ id) => {
      const el = /** @type {HTMLInputElement|HTMLSelectElement|null} */ (document.getElementById(id));
      return el ? el.value : "";
    };
    return exportQuery(format, {
      fps: this.fields.fps.value, source: this.fields.source.value,
      scale: this.fields.scale.value, offset: this.fields.offset.value,
    }, { preset: value("sim-preset"), seed: value("sim-seed"), controller: value("sim-controller"),
      disturbance: value("sim-disturbance") });
  }

  /** Open the export options at the origin field with `message` under it. @param {string} message */
  _pointAtOrigin(message) {
    const details = /** @type {HTMLDetailsElement} */ (document.getElementById("export-options"));
    details.open = true;
    document.querySelector('[data-error-for="origin"]').textContent = message;
    this.fields.origin.focus();
  }

  /** Ask the server which formats it offers and fill the menu. */
  async load() {
    const formats = await api.exportFormats();
    this.select.replaceChildren();
    for (const f of formats) {
      const o = document.createElement("option");
      o.value = f;
      o.textContent = FORMAT_LABELS[f] || f;
      this.select.append(o);
    }
  }

  /** Save if needed, then download the chosen format. */
  async run() {
    const st = this.state;
    if (!st.meta) return;
    const el = document.getElementById("export-error");
    this._clearErrors();
    const format = this.select.value;
    // Known before asking the server (a 422 in the browser console otherwise): the QGC formats need the origin,
    // and only some formats hold the simulated trajectories.
    const problem = exportProblem(format, st.show && st.show.settings.geo, this.fields.source.value);
    if (problem) {
      el.textContent = `${FORMAT_LABELS[format] || format}: ${problem}`;
      if (/origin/i.test(problem)) this._pointAtOrigin(problem);
      else {
        /** @type {HTMLDetailsElement} */ (document.getElementById("export-options")).open = true;
        this.fields.source.focus();
      }
      return;
    }
    this.button.disabled = true;
    this.button.setAttribute("aria-busy", "true");
    const old = this.button.textContent;
    this.button.textContent = "Exporting…";
    try {
      if (!(await this.persist.ensureSaved())) {
        el.textContent = "Not exported: the show could not be saved.";
        return;
      }
      const draft = this.persist.draftRefusal("exported", true);
      if (draft) {
        el.textContent = draft;
        return;
      }
      const { blob, filename, warnings } = await api.exportShow(st.meta.id, format, this.options(format));
      downloadBlob(blob, filename);
      toast(warnings.length ? `Downloaded ${filename} (${warnings.join("; ")})` : `Downloaded ${filename}`, { ms: warnings.length ? 8000 : 2500 });
    } catch (err) {
      el.textContent = `${FORMAT_LABELS[format] || format}: ${err.message}`;
      const problems = err instanceof api.ApiError && Array.isArray(err.problems) ? err.problems : [];
      if (problems.some((p) => /^formations\[\d+\]/.test(p.path || ""))) {
        // As the check does: the formation the refusal names is marked on its timeline card.
        showShowErrors(problems.filter((p) => /^formations\[\d+\]/.test(p.path || "")), () => {});
        if (this.hooks.onFormationProblems) this.hooks.onFormationProblems();
      }
      if (/origin/i.test(err.message)) this._pointAtOrigin(err.message);
    } finally {
      this.button.textContent = old;
      this.button.disabled = false;
      this.button.removeAttribute("aria-busy");
    }
  }
}
