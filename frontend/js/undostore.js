// Undo history that survives a reload of the page: kept in sessionStorage (this tab only) per
// show, next to the document it belongs to, and put back when that same document is opened.

const KEY = "swarmshow.undo.";
/** Steps kept per stack (whole-document steps of big shows are large). */
const KEEP = 30;
/** sessionStorage holds a few MB: a history above this is cut to its newest steps. */
const MAX_CHARS = 3_000_000;

/**
 * Keep `state`'s history in sessionStorage and restore it on reload.
 * @param {import("./state.js").EditorState} state
 */
export function keepUndoAcrossReloads(state) {
  let timer = 0;
  const write = () => {
    timer = 0;
    if (!state.show || !state.meta) return;
    const doc = JSON.stringify(state.show);
    for (let keep = KEEP; keep >= 1; keep = Math.floor(keep / 2)) {
      const text = JSON.stringify({ doc, history: state.exportHistory(keep) });
      if (text.length > MAX_CHARS && keep > 1) continue;
      try {
        sessionStorage.setItem(KEY + state.meta.id, text);
      } catch {
        sessionStorage.removeItem(KEY + state.meta.id); // full: better no history than a wrong one
      }
      return;
    }
  };
  state.addEventListener("change", (e) => {
    const kind = e.detail.kind;
    if (kind === "load") {
      clearTimeout(timer);
      timer = 0;
      const saved = state.meta && sessionStorage.getItem(KEY + state.meta.id);
      if (!saved) return;
      try {
        const { doc, history } = JSON.parse(saved);
        if (doc === JSON.stringify(state.show)) queueMicrotask(() => state.importHistory(history));
      } catch {
        sessionStorage.removeItem(KEY + state.meta.id);
      }
      return;
    }
    if (kind === "edit" || kind === "saved") {
      clearTimeout(timer);
      timer = setTimeout(write, 400);
    }
  });
  addEventListener("pagehide", () => { if (timer) { clearTimeout(timer); write(); } });
}
