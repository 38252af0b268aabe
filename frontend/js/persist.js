// @ts-check
// Saving: explicit (Ctrl+S) or automatic, revision-checked. A 409 opens a choice (overwrite,
// save as a copy, reload theirs, decide later) and the user's work is never dropped silently:
// unsaved edits are also kept in localStorage until they are saved.

import * as api from "./api.js";
import { confirmAction, toast } from "./dialogs.js";
import { clearShowErrors, showShowErrors } from "./errors.js";
import { recordMeta } from "./state.js";

const DRAFT_PREFIX = "swarmshow.draft.";
const AUTOSAVE_KEY = "swarmshow.autosave";
const AUTOSAVE_DELAY_MS = 3000;

/** Keeps the open show in sync with the server. */
export class Persistence extends EventTarget {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {{status: (msg: string, error?: boolean) => void, rendered: () => void}} ui
   */
  constructor(state, ui) {
    super();
    this.state = state;
    this.ui = ui;
    this.saving = null;
    this.conflictOpen = false;
    this.autosave = localStorage.getItem(AUTOSAVE_KEY) === "1";
    this._autoTimer = 0;
    this._draftTimer = 0;
    state.addEventListener("change", (/** @type {any} */ e) => {
      if (e.detail.kind !== "edit") return;
      this._scheduleDraft();
      if (this.autosave) {
        clearTimeout(this._autoTimer);
        this._autoTimer = setTimeout(() => { if (this.state.dirty && !this.conflictOpen) this.save(); }, AUTOSAVE_DELAY_MS);
      }
    });
    window.addEventListener("beforeunload", (e) => {
      if (this.state.dirty) {
        this._writeDraft();
        e.preventDefault();
        e.returnValue = "";
      }
    });
    this._wireConflictDialog();
  }

  /** @param {boolean} on */
  setAutosave(on) {
    this.autosave = on;
    localStorage.setItem(AUTOSAVE_KEY, on ? "1" : "0");
    if (on && this.state.dirty) this.save();
  }

  _scheduleDraft() {
    clearTimeout(this._draftTimer);
    this._draftTimer = setTimeout(() => this._writeDraft(), 800);
  }

  _writeDraft() {
    const st = this.state;
    if (!st.meta) return;
    const key = DRAFT_PREFIX + st.meta.id;
    try {
      if (st.dirty) localStorage.setItem(key, JSON.stringify({ revision: st.meta.revision, saved_at: new Date().toISOString(), show: st.show }));
      else localStorage.removeItem(key);
    } catch {
      // Storage full or unavailable: the unsaved-changes warning on leaving still protects the work.
    }
  }

  /**
   * Unsaved edits kept from an earlier session for this show, if any.
   * @param {string} id
   * @returns {{revision: number, saved_at: string, show: any}|null}
   */
  draftFor(id) {
    try {
      const raw = localStorage.getItem(DRAFT_PREFIX + id);
      return raw ? JSON.parse(raw) : null;
    } catch {
      return null;
    }
  }

  /** @param {string} id */
  dropDraft(id) {
    localStorage.removeItem(DRAFT_PREFIX + id);
  }

  /**
   * Save the show if it has unsaved changes (or `force`).
   * @param {{force?: boolean}} [opts]
   * @returns {Promise<boolean>} true when the server holds exactly what is on screen
   */
  async save(opts = {}) {
    const st = this.state;
    if (!st.show || !st.meta) return false;
    if (this.saving) {
      await this.saving;
      if (!st.dirty && !opts.force) return true;
    }
    if (!st.dirty && !opts.force) return true;
    if (this.conflictOpen) return false;
    const run = this._put(st.meta.revision);
    this.saving = run;
    try {
      return await run;
    } finally {
      this.saving = null;
    }
  }

  async _put(revision) {
    const st = this.state;
    const version = st.version;
    const doc = structuredClone(st.show);
    this.ui.status("Saving…");
    try {
      // Half-finished work is kept as a draft (with its problems) rather than refused: check,
      // simulate and export then say what is wrong until it is saved valid.
      const rec = await api.updateShow(st.meta.id, doc, revision, { draft: true });
      clearShowErrors();
      st.meta.revision = rec.revision;
      st.meta.draft = rec.draft;
      st.meta.problems = rec.problems;
      if (st.version === version) {
        st.markSaved(rec.revision);
        this.dropDraft(st.meta.id);
      }
      if (rec.draft) {
        showShowErrors(rec.problems, () => {});
        const n = rec.problems.length;
        const first = rec.problems[0];
        this.ui.status(`Saved as a draft · revision ${rec.revision} · ${n} problem${n > 1 ? "s" : ""}: ${first ? `${first.where || first.path}: ${first.msg}` : ""}`, true);
      } else {
        this.ui.status(`Saved · revision ${rec.revision}`);
      }
      this.ui.rendered();
      this.dispatchEvent(new CustomEvent("draft", { detail: rec }));
      return st.version === version;
    } catch (err) {
      if (err instanceof api.ApiError && err.status === 409) {
        this._writeDraft();
        this.ui.status("Not saved: the show was changed elsewhere", true);
        this._openConflict(err);
        return false;
      }
      if (err instanceof api.ApiError && err.status === 422) {
        clearShowErrors();
        showShowErrors(err.problems, (msg) => this.ui.status(`Not saved: ${msg}`, true));
        this.ui.status(`Not saved: ${err.message}`, true);
        this.ui.rendered();
        return false;
      }
      this.ui.status(`Not saved: ${err.message}`, true);
      return false;
    }
  }

  _wireConflictDialog() {
    const dlg = /** @type {HTMLDialogElement} */ (document.getElementById("dlg-conflict"));
    const close = () => { dlg.close(); this.conflictOpen = false; };
    document.getElementById("btn-conflict-overwrite").addEventListener("click", async () => {
      close();
      await this.overwrite();
    });
    document.getElementById("btn-conflict-copy").addEventListener("click", async () => {
      close();
      await this.saveCopy();
    });
    document.getElementById("btn-conflict-reload").addEventListener("click", async () => {
      const ok = await confirmAction("Discard your changes?", "Reloading replaces what is on screen with the stored version; your unsaved changes are lost.", "Reload theirs");
      if (!ok) return;
      close();
      await this.reload();
    });
    document.getElementById("btn-conflict-cancel").addEventListener("click", () => {
      close();
      this.ui.status("Not saved: the show was changed elsewhere (Save again to choose)", true);
    });
    dlg.addEventListener("cancel", () => { this.conflictOpen = false; });
  }

  _openConflict(err) {
    const dlg = /** @type {HTMLDialogElement} */ (document.getElementById("dlg-conflict"));
    const current = err.body && err.body.current_revision;
    const mine = this.state.meta.revision;
    document.getElementById("dlg-conflict-msg").textContent =
      `Someone (or another tab) saved this show since you opened it: the stored revision is ${current ?? "newer"}, ` +
      `your edits are based on revision ${mine}.`;
    this.conflictOpen = true;
    if (!dlg.open) dlg.showModal();
  }

  /** Replace the stored show with the one on screen, whatever its revision now. */
  async overwrite() {
    const st = this.state;
    try {
      const latest = await api.getShow(st.meta.id);
      return await this._put(latest.revision);
    } catch (err) {
      if (err instanceof api.ApiError && err.status === 404) {
        return this.saveCopy();
      }
      this.ui.status(`Not saved: ${err.message}`, true);
      return false;
    }
  }

  /** Store the show on screen as a new show and continue editing that one. */
  async saveCopy() {
    const st = this.state;
    const doc = structuredClone(st.show);
    if (!/\(copy\)$/.test(doc.name)) doc.name = `${doc.name} (copy)`.slice(0, 200);
    try {
      // The copy keeps the work as it is: a draft if it is half-finished.
      const rec = await api.createShow(doc, { draft: true });
      const oldId = st.meta.id;
      // The music goes with the copy (before the load below, which reloads the music lane).
      let musicLost = "";
      let copied = null;
      try {
        copied = await api.copyAudio(rec.id, oldId);
      } catch (err) {
        musicLost = ` (its music was not copied: ${err.message})`;
      }
      st.load(rec.show, recordMeta({ ...rec, has_audio: !!copied }), { keepCurrent: true });
      this.dropDraft(oldId);
      this.dispatchEvent(new CustomEvent("opened", { detail: rec }));
      this.ui.status(`Saved as a new show "${rec.name}"${musicLost}`, !!musicLost);
      toast(`Your version was saved as "${rec.name}"`);
      return true;
    } catch (err) {
      if (err instanceof api.ApiError && err.status === 422) showShowErrors(err.problems, (m) => this.ui.status(m, true));
      this.ui.status(`Not saved: ${err.message}`, true);
      return false;
    }
  }

  /** Load the stored version of the open show (the caller has confirmed discarding edits). */
  async reload() {
    const st = this.state;
    try {
      const rec = await api.getShow(st.meta.id);
      this.dropDraft(rec.id);
      st.load(rec.show, recordMeta(rec), { keepCurrent: true });
      clearShowErrors();
      this.dispatchEvent(new CustomEvent("opened", { detail: rec }));
      this.ui.status(`Reloaded revision ${rec.revision}`);
      return true;
    } catch (err) {
      this.ui.status(`Cannot reload: ${err.message}`, true);
      return false;
    }
  }

  /**
   * When the stored show is a draft (the save listed its problems), why `verb` ("checked", "simulated",
   * "exported") is not asked of the server, which would refuse it with 422: the draft panel is brought into
   * view and the message points at it. "" for a valid show.
   * @param {string} verb @param {boolean} [short] one short line (the top bar's export message)
   * @returns {string}
   */
  draftRefusal(verb, short = false) {
    const meta = this.state.meta;
    if (!meta || !meta.draft) return "";
    const n = (meta.problems || []).length;
    document.getElementById("draft-panel")?.scrollIntoView({ block: "nearest" });
    if (short) return `Not ${verb}: a draft, see the draft panel`;
    return `Not ${verb}: the show is a draft with ${n} problem${n === 1 ? "" : "s"}; fix ${n === 1 ? "it" : "them"} `
      + "as listed in the draft panel (“Draft: not ready yet”), then save.";
  }

  /**
   * Make sure the server has what is on screen before an action on the stored show (check, export...).
   * @returns {Promise<boolean>}
   */
  async ensureSaved() {
    if (!this.state.dirty) return true;
    return this.save();
  }
}
