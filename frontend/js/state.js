// @ts-check
// The open show: the document, which formation and points are selected, undo/redo, dirty flag.
// Undo stores per-formation diffs: an undo step keeps, as JSON text, only the formations the
// edit replaced and the ones it put in their place (one splice of the formation list), plus the
// show's other fields only when they changed. Moving one point of a 20 MB show costs one
// formation's text per step, not two copies of the document; the stack is bounded.

const MAX_UNDO = 100;

/** Skybrush's defaults (a de facto standard for show settings). */
export const DEFAULT_SETTINGS = Object.freeze({
  min_distance_m: 3.0,
  max_speed_xy_mps: 10.0,
  max_speed_z_mps: 2.0,
  max_accel_mps2: 4.0,
  max_altitude_m: 150.0,
  takeoff_altitude_m: 10.0,
});

/**
 * Colours of a formation as one array of `#rrggbb` (expanding `color`).
 * @param {{points: number[][], colors?: string[], color?: string}} f
 * @returns {string[]}
 */
export function formationColors(f) {
  if (Array.isArray(f.colors) && f.colors.length === f.points.length) return f.colors;
  return f.points.map(() => f.color || "#ffffff");
}

/**
 * A formation with one colour per point (`colors`), `color` dropped.
 * @param {any} f
 */
export function withColors(f) {
  const colors = formationColors(f).slice();
  const { color: _c, ...rest } = f;
  return { ...rest, colors };
}

function clone(obj) {
  return structuredClone(obj);
}

/** The show's fields other than `formations`, as JSON text (settings, home, name, ...). */
function restText(show) {
  const { formations: _f, ...rest } = show;
  return JSON.stringify(rest);
}

/**
 * The document as text, formation by formation (what an edit is diffed against).
 * @param {any} show
 * @returns {{formations: string[], rest: string}}
 */
function documentText(show) {
  return { formations: show.formations.map((f) => JSON.stringify(f)), rest: restText(show) };
}

/**
 * The smallest single splice turning `before` into `after` (common prefix and suffix kept).
 * @param {string[]} before
 * @param {string[]} after
 * @returns {{start: number, before: string[], after: string[]}}
 */
export function spliceDiff(before, after) {
  let start = 0;
  while (start < before.length && start < after.length && before[start] === after[start]) start++;
  let endB = before.length;
  let endA = after.length;
  while (endB > start && endA > start && before[endB - 1] === after[endA - 1]) { endB--; endA--; }
  return { start, before: before.slice(start, endB), after: after.slice(start, endA) };
}

/** Shortest and longest hold or transition the show file takes, seconds (formations/_show.py: MIN_DURATION_S, 86,400). */
export const MIN_DURATION_S = 0.01;
export const MAX_DURATION_S = 86_400;

/**
 * What is wrong with a typed hold or transition duration, or "" when the show file takes it.
 * @param {number} seconds
 * @returns {string}
 */
export function durationProblem(seconds) {
  if (!Number.isFinite(seconds)) return "must be a number of seconds";
  if (seconds < MIN_DURATION_S) return `must be at least ${MIN_DURATION_S} s`;
  if (seconds > MAX_DURATION_S) return `must be at most ${MAX_DURATION_S} s (24 hours)`;
  return "";
}

/**
 * Where an open show is stored: its id and revision, whether it is a draft (and what is wrong), and whether it
 * has music (the music lane asks for the track only then: asking a show without music is a 404).
 * @typedef {{id: string, revision: number, draft?: boolean, problems?: any[], has_audio?: boolean}} ShowMeta
 */

/**
 * The `ShowMeta` of a show record as the API answers it (GET, POST or PUT /api/shows).
 * @param {{id: string, revision: number, draft?: boolean, problems?: any[], has_audio?: boolean}} rec
 * @returns {ShowMeta}
 */
export function recordMeta(rec) {
  return { id: rec.id, revision: rec.revision, draft: rec.draft, problems: rec.problems, has_audio: !!rec.has_audio };
}

/** The editor state. Listen with `store.addEventListener("change", ...)`; `detail.kind` says what changed. */
export class EditorState extends EventTarget {
  constructor() {
    super();
    /** @type {any|null} the swarmshow/1 document being edited */
    this.show = null;
    /** @type {ShowMeta|null} where it is stored (a draft: with what is wrong) */
    this.meta = null;
    this.current = 0;
    /** @type {Set<number>} selected point indices of the current formation */
    this.selection = new Set();
    this.undoStack = [];
    this.redoStack = [];
    this.version = 0;
    this.savedVersion = 0;
    this._nextVersion = 1;
    this._pending = null;
  }

  /** @returns {boolean} there are changes not yet saved. */
  get dirty() {
    return this.show !== null && this.version !== this.savedVersion;
  }

  /** @returns {any|null} the formation being edited. */
  get formation() {
    return this.show ? this.show.formations[this.current] ?? null : null;
  }

  _emit(kind) {
    this.dispatchEvent(new CustomEvent("change", { detail: { kind } }));
  }

  /**
   * Open a show (drops the undo history).
   * @param {any} show
   * @param {ShowMeta} meta
   * @param {{keepCurrent?: boolean}} [opts] keep the formation index (reloading the same show)
   */
  load(show, meta, opts = {}) {
    const s = clone(show);
    s.settings = { ...DEFAULT_SETTINGS, ...(s.settings || {}) };
    s.formations = s.formations.map(withColors);
    this.show = s;
    this.meta = meta ? { ...meta } : null;
    this.current = opts.keepCurrent ? Math.min(this.current, s.formations.length - 1) : 0;
    this.selection = new Set();
    this.undoStack = [];
    this.redoStack = [];
    this.version = this._nextVersion++;
    this.savedVersion = this.version;
    this._emit("load");
  }

  /** Close the show. */
  close() {
    this.show = null;
    this.meta = null;
    this.selection = new Set();
    this.undoStack = [];
    this.redoStack = [];
    this._emit("load");
  }

  /** Remember the document before a multi-step edit (e.g. a drag); finish it with {@link commit}. */
  checkpoint() {
    if (!this.show) return;
    this._pending = { text: documentText(this.show), current: this.current, selection: [...this.selection], version: this.version };
  }

  /** Forget a checkpoint without recording or restoring anything (the gesture changed nothing). */
  discard() {
    this._pending = null;
  }

  /** Drop a checkpoint and restore the document it remembered (e.g. Escape during a drag). */
  rollback() {
    if (!this._pending) return;
    const p = this._pending;
    this.show = { ...JSON.parse(p.text.rest), formations: p.text.formations.map((f) => JSON.parse(f)) };
    this.current = Math.min(p.current, this.show.formations.length - 1);
    this.selection = new Set(p.selection);
    this.version = p.version;
    this._pending = null;
    this._emit("edit");
  }

  /**
   * Record the edit since {@link checkpoint} as one undo step.
   * @param {string} label what the edit did (shown in the undo button's title)
   */
  commit(label) {
    if (!this._pending) return;
    const p = this._pending;
    const now = documentText(this.show);
    const diff = spliceDiff(p.text.formations, now.formations);
    const version = this._nextVersion++;
    this.undoStack.push({
      label,
      start: diff.start,
      before: diff.before,
      after: diff.after,
      restBefore: p.text.rest === now.rest ? null : p.text.rest,
      restAfter: p.text.rest === now.rest ? null : now.rest,
      currentBefore: p.current,
      currentAfter: this.current,
      selectionBefore: p.selection,
      selectionAfter: [...this.selection],
      versionBefore: p.version,
      versionAfter: version,
    });
    if (this.undoStack.length > MAX_UNDO) this.undoStack.shift();
    this.redoStack = [];
    this._pending = null;
    this.version = version;
    this._emit("edit");
  }

  /**
   * One undoable edit: `fn` mutates `this.show` (and may change selection / current).
   * If `fn` returns false, nothing is recorded.
   * @param {string} label
   * @param {() => (void|boolean)} fn
   */
  edit(label, fn) {
    if (!this.show) return;
    this.checkpoint();
    let changed;
    try {
      changed = fn();
    } catch (err) {
      this.rollback();
      throw err;
    }
    if (changed === false) {
      this._pending = null;
      return;
    }
    this.commit(label);
  }

  /**
   * Apply one side of an undo step: put back the formations of `side` in place of the other's.
   * @param {any} step an entry of undoStack / redoStack
   * @param {"before"|"after"} side
   */
  _apply(step, side) {
    const other = side === "before" ? "after" : "before";
    const fs = this.show.formations;
    fs.splice(step.start, step[other].length, ...step[side].map((f) => JSON.parse(f)));
    const rest = side === "before" ? step.restBefore : step.restAfter;
    if (rest !== null) this.show = { ...JSON.parse(rest), formations: fs };
    const current = side === "before" ? step.currentBefore : step.currentAfter;
    this.current = Math.max(0, Math.min(current, fs.length - 1));
    this.selection = new Set(side === "before" ? step.selectionBefore : step.selectionAfter);
    this.version = side === "before" ? step.versionBefore : step.versionAfter;
  }

  /** @returns {boolean} whether there was something to undo. */
  undo() {
    const step = this.undoStack.pop();
    if (!step) return false;
    this._apply(step, "before");
    this.redoStack.push(step);
    this._emit("edit");
    return true;
  }

  /** @returns {boolean} whether there was something to redo. */
  redo() {
    const step = this.redoStack.pop();
    if (!step) return false;
    this._apply(step, "after");
    this.undoStack.push(step);
    this._emit("edit");
    return true;
  }

  /** Mark the current document as saved at `revision`. */
  markSaved(revision) {
    if (this.meta) this.meta.revision = revision;
    this.savedVersion = this.version;
    this._emit("saved");
  }

  /**
   * Select a formation (not an undo step).
   * @param {number} index
   */
  setCurrent(index) {
    if (!this.show) return;
    const k = Math.max(0, Math.min(index, this.show.formations.length - 1));
    if (k !== this.current) {
      this.current = k;
      this.selection = new Set();
    }
    this._emit("current");
  }

  /**
   * Replace the point selection (not an undo step).
   * @param {Iterable<number>} indices
   */
  setSelection(indices) {
    this.selection = new Set(indices);
    this._emit("selection");
  }

  /**
   * The undo and redo history as plain data (structured-clonable), newest last, at most `limit`
   * steps each; with {@link importHistory} it outlives a page reload.
   * @param {number} [limit]
   */
  exportHistory(limit = MAX_UNDO) {
    return { undo: this.undoStack.slice(-limit), redo: this.redoStack.slice(-limit) };
  }

  /**
   * Put back a history from {@link exportHistory} over the same document (just loaded). Its steps
   * get versions no save has, so undoing into them marks the document unsaved.
   * @param {{undo: any[], redo: any[]}} history
   */
  importHistory(history) {
    if (!this.show || !history || !Array.isArray(history.undo) || !Array.isArray(history.redo)) return;
    // Steps are diffs between versions: the chain is renumbered so that the step next to the
    // document (the top of each stack) meets the loaded version and every other version is new
    // (no save has it, so undoing into one marks the document unsaved).
    const undo = history.undo.map((step) => ({ ...step }));
    const redo = history.redo.map((step) => ({ ...step }));
    let v = this.version;
    for (let i = undo.length - 1; i >= 0; i--) {
      undo[i].versionAfter = v;
      v = this._nextVersion++;
      undo[i].versionBefore = v;
    }
    v = this.version;
    for (let i = redo.length - 1; i >= 0; i--) {
      redo[i].versionBefore = v;
      v = this._nextVersion++;
      redo[i].versionAfter = v;
    }
    this.undoStack = undo;
    this.redoStack = redo;
    this._emit("history");
  }

  /** Tell listeners the document changed during a live (uncommitted) edit, e.g. a drag. */
  touch() {
    this._emit("live");
  }
}
