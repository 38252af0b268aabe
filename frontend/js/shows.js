// @ts-check
// The shows dialog: list, open, create (drone count, home grid), rename, delete, import and
// export show files.

import * as api from "./api.js";
import { askText, choose, confirmAction, toast } from "./dialogs.js";
import { setError } from "./errors.js";
import { DEFAULT_SETTINGS, recordMeta } from "./state.js";
import { gridFormation } from "./timeline.js";

/**
 * A new show document: `drones` on a `rows` x `cols` home grid, one grid formation.
 * @param {{name: string, drones: number, rows: number, cols: number, spacing_m: number}} p
 * @returns {any}
 */
export function newShowDocument(p) {
  const settings = { ...DEFAULT_SETTINGS, min_distance_m: Math.min(DEFAULT_SETTINGS.min_distance_m, p.spacing_m) };
  const show = {
    format: "swarmshow/1",
    name: p.name,
    drones: p.drones,
    home: { grid: { rows: p.rows, cols: p.cols, spacing_m: p.spacing_m } },
    settings,
    formations: [],
  };
  show.formations.push(gridFormation(show, "Formation 1"));
  return show;
}

/**
 * Save a Blob as a file in the browser's downloads.
 * @param {Blob} blob @param {string} filename
 */
export function downloadBlob(blob, filename) {
  const url = URL.createObjectURL(blob);
  const a = document.createElement("a");
  a.href = url;
  a.download = filename;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}

/** The shows dialog. */
export class ShowsDialog {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {import("./persist.js").Persistence} persist
   * @param {(rec: any) => void} onOpen called with the record of a show that was opened
   */
  constructor(state, persist, onOpen) {
    this.state = state;
    this.persist = persist;
    this.onOpen = onOpen;
    this.dlg = /** @type {HTMLDialogElement} */ (document.getElementById("dlg-shows"));
    this.tbody = document.getElementById("shows-tbody");
    document.getElementById("btn-shows-close").addEventListener("click", () => this.dlg.close());
    const rows = /** @type {HTMLInputElement} */ (document.getElementById("new-rows"));
    const cols = /** @type {HTMLInputElement} */ (document.getElementById("new-cols"));
    const drones = /** @type {HTMLInputElement} */ (document.getElementById("new-drones"));
    drones.addEventListener("input", () => {
      const n = Math.max(1, Number(drones.value) || 1);
      const c = Math.ceil(Math.sqrt(n));
      cols.value = String(c);
      rows.value = String(Math.ceil(n / c));
    });
    document.getElementById("form-new-show").addEventListener("submit", (e) => {
      e.preventDefault();
      this._create();
    });
    document.getElementById("import-file").addEventListener("change", (e) => this._import(e.target));
  }

  /** Open the dialog and load the list. */
  async open() {
    if (!this.dlg.open) this.dlg.showModal();
    await this.refresh();
  }

  /** Reload the list of shows. */
  async refresh() {
    setError("shows-list", "");
    let items;
    try {
      items = await api.listShows();
    } catch (err) {
      setError("shows-list", `Cannot list shows: ${err.message}`);
      return;
    }
    this.tbody.replaceChildren();
    if (!items.length) {
      const tr = document.createElement("tr");
      const td = document.createElement("td");
      td.colSpan = 5;
      td.className = "muted";
      td.textContent = "No shows yet: create one on the right, or import a show file.";
      tr.append(td);
      this.tbody.append(tr);
    }
    for (const s of items) this.tbody.append(this._row(s));
  }

  _row(s) {
    const tr = document.createElement("tr");
    if (this.state.meta && this.state.meta.id === s.id) tr.className = "current";
    const name = document.createElement("td");
    const open = document.createElement("button");
    open.type = "button";
    open.textContent = s.name;
    open.setAttribute("aria-label", `Open show ${s.name}`);
    open.addEventListener("click", () => this.openShow(s.id));
    name.append(open);
    if (s.draft) {
      const tag = document.createElement("span");
      tag.className = "draft-tag";
      tag.textContent = "draft";
      tag.title = `Saved half-finished: ${(s.problems || []).length} problem(s)`;
      name.append(" ", tag);
    }
    const cells = [s.drones, s.formations, s.updated_at ? new Date(s.updated_at).toLocaleString() : ""].map((v) => {
      const td = document.createElement("td");
      td.textContent = String(v ?? "");
      return td;
    });
    const actions = document.createElement("td");
    actions.className = "actions";
    const mk = (label, aria, fn) => {
      const b = document.createElement("button");
      b.type = "button";
      b.textContent = label;
      b.setAttribute("aria-label", aria);
      b.addEventListener("click", fn);
      actions.append(b, " ");
    };
    mk("Rename", `Rename show ${s.name}`, () => this._rename(s));
    mk("Export", `Download the show file of ${s.name}`, () => this._exportFile(s));
    mk("Delete", `Delete show ${s.name}`, () => this._delete(s));
    tr.append(name, ...cells, actions);
    return tr;
  }

  /** Ask what to do with unsaved changes before leaving the open show. @returns {Promise<boolean>} go on */
  async _leaveCurrent() {
    if (!this.state.dirty) return true;
    const { choice } = await choose({
      title: "Unsaved changes",
      message: `"${this.state.show.name}" has unsaved changes.`,
      buttons: [
        { label: "Save them", value: "save", primary: true },
        { label: "Discard them", value: "discard" },
        { label: "Cancel", value: "cancel" },
      ],
    });
    if (choice === "save") return this.persist.save();
    if (choice === "discard") {
      this.persist.dropDraft(this.state.meta.id);
      return true;
    }
    return false;
  }

  /**
   * Open a stored show (offering to restore unsaved edits kept from an earlier session).
   * @param {string} id
   */
  async openShow(id) {
    if (this.state.meta && this.state.meta.id === id && !this.state.dirty) {
      this.dlg.close();
      return;
    }
    if (!(await this._leaveCurrent())) return;
    let rec;
    try {
      rec = await api.getShow(id);
    } catch (err) {
      setError("shows-list", `Cannot open: ${err.message}`);
      return;
    }
    this.state.load(rec.show, recordMeta(rec));
    const draft = this.persist.draftFor(id);
    if (draft) {
      const { choice } = await choose({
        title: "Unsaved changes found",
        message: `This browser kept unsaved changes to "${rec.name}" from ${new Date(draft.saved_at).toLocaleString()} (based on revision ${draft.revision}; stored: ${rec.revision}).`,
        buttons: [{ label: "Restore them", value: "restore", primary: true }, { label: "Discard them", value: "discard" }],
      });
      if (choice === "restore") {
        this.state.edit("Restore unsaved changes", () => {
          this.state.show = draft.show;
          this.state.current = 0;
        });
        this.state.meta.revision = draft.revision;
      } else if (choice === "discard") this.persist.dropDraft(id);
    }
    localStorage.setItem("swarmshow.last", id);
    if (this.dlg.open) this.dlg.close();
    this.onOpen(rec);
  }

  async _create() {
    setError("new-show", "");
    const v = (id) => /** @type {HTMLInputElement} */ (document.getElementById(id)).value;
    const p = {
      name: v("new-name").trim() || "New show",
      drones: Math.round(Number(v("new-drones"))),
      rows: Math.round(Number(v("new-rows"))),
      cols: Math.round(Number(v("new-cols"))),
      spacing_m: Number(v("new-spacing")),
    };
    if (!(p.drones >= 1)) return setError("new-show", "Drones: at least 1");
    if (p.rows * p.cols < p.drones) return setError("new-show", `Home grid ${p.rows} × ${p.cols} has fewer places than ${p.drones} drones`);
    if (!(await this._leaveCurrent())) return;
    try {
      const doc = newShowDocument(p);
      const rec = await api.createShow(doc);
      this.state.load(rec.show, recordMeta(rec));
      localStorage.setItem("swarmshow.last", rec.id);
      this.dlg.close();
      this.onOpen(rec);
      // A home grid closer than the default minimum distance lowers it to the spacing: said, not done silently.
      const d = doc.settings.min_distance_m;
      toast(d < DEFAULT_SETTINGS.min_distance_m
        ? `Created "${rec.name}" with a minimum distance ${d} m between drones (the home grid's spacing; `
          + `the default is ${DEFAULT_SETTINGS.min_distance_m} m): Show settings to change it`
        : `Created "${rec.name}"`, { ms: d < DEFAULT_SETTINGS.min_distance_m ? 8000 : 2500 });
    } catch (err) {
      setError("new-show", err.message);
    }
  }

  async _import(input) {
    setError("import", "");
    const file = input.files && input.files[0];
    input.value = "";
    if (!file) return;
    if (!(await this._leaveCurrent())) return;
    try {
      let text = await file.text();
      // A name already in the store gets " (2)", " (3)", ...: two shows of one name are easy to confuse.
      const doc = (() => { try { return JSON.parse(text); } catch { return null; } })();
      if (doc && typeof doc === "object" && typeof doc.name === "string") {
        const taken = new Set((await api.listShows()).map((r) => r.name));
        const base = doc.name.replace(/ \(\d+\)$/, "");
        let name = doc.name;
        for (let k = 2; taken.has(name); k++) name = `${base} (${k})`;
        if (name !== doc.name) text = JSON.stringify({ ...doc, name });
      }
      const res = await api.request("POST", "/api/shows", { body: text, headers: { "Content-Type": "application/json" } });
      const rec = api.normalizeRecord(res);
      this.state.load(rec.show, recordMeta(rec));
      localStorage.setItem("swarmshow.last", rec.id);
      this.dlg.close();
      this.onOpen(rec);
      toast(`Imported "${rec.name}"`);
    } catch (err) {
      setError("import", `${file.name}: ${err.message}`);
    }
  }

  async _rename(s) {
    const name = await askText("Rename show", "New name", s.name);
    if (!name || name === s.name) return;
    if (this.state.meta && this.state.meta.id === s.id) {
      this.state.edit("Rename show", () => { this.state.show.name = name; });
      await this.persist.save();
    } else {
      try {
        const rec = await api.getShow(s.id);
        rec.show.name = name;
        await api.updateShow(s.id, rec.show, rec.revision);
      } catch (err) {
        setError("shows-list", `Cannot rename: ${err.message}`);
      }
    }
    await this.refresh();
  }

  async _exportFile(s) {
    try {
      const { blob, filename } = await api.exportShow(s.id, "show");
      downloadBlob(blob, filename);
    } catch (err) {
      setError("shows-list", `Cannot export: ${err.message}`);
    }
  }

  async _delete(s) {
    const ok = await confirmAction("Delete show", `Delete "${s.name}" for good? This cannot be undone.`, "Delete");
    if (!ok) return;
    try {
      await api.deleteShow(s.id);
      this.persist.dropDraft(s.id);
      if (this.state.meta && this.state.meta.id === s.id) {
        this.state.close();
        this.onOpen(null);
      }
    } catch (err) {
      setError("shows-list", `Cannot delete: ${err.message}`);
    }
    await this.refresh();
  }
}
