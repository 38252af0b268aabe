// @ts-check
// "3D preview": the viser viewer (/viser/, same origin) beside or over the canvas, loaded with
// the saved show through POST /api/shows/{id}/playback.

import * as api from "./api.js";
import { setError } from "./errors.js";

/** The 3D preview pane. */
export class Preview {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {import("./persist.js").Persistence} persist
   * @param {() => void} onLayout called when the canvas size changes
   * @param {() => ("planned"|"simulated")} [source] what to play: the simulated flight once one exists
   * @param {() => ({job_id: string}|undefined)} [flight] the simulation job whose flight (its preset and
   *   seed) "simulated" plays; none: the default flight
   */
  constructor(state, persist, onLayout, source = () => "planned", flight = () => undefined) {
    this.source = source;
    this.flight = flight;
    this.state = state;
    this.persist = persist;
    this.onLayout = onLayout;
    this.wrap = document.getElementById("preview-wrap");
    this.frame = /** @type {HTMLIFrameElement} */ (document.getElementById("preview-frame"));
    this.button = document.getElementById("btn-preview");
    this.over = /** @type {HTMLInputElement} */ (document.getElementById("preview-over"));
    this.over.checked = localStorage.getItem("swarmshow.previewOver") === "1";
    this.over.addEventListener("change", () => {
      localStorage.setItem("swarmshow.previewOver", this.over.checked ? "1" : "0");
      this._layout();
    });
    /** @type {number|null} the formation whose hold a new viewer page starts at (the playhead seeks it there) */
    this.startFormation = null;
    /** @type {number|null} the time a new viewer page starts at instead (a flight's closest pair), seconds */
    this.startTime = null;
    /** @type {MutationObserver|null} the watch on the viewer page that folds viser's bottom sheet (foldSheet) */
    this.sheetWatch = null;
    /** whether a fold is due at the next animation frame (the page's changes in one frame: one look) */
    this.foldDue = false;
    // Each viewer page is watched from its load: viser renders its panel (React) after the page has loaded.
    this.frame.addEventListener("load", () => this._watchSheet());
    document.getElementById("btn-preview-close").addEventListener("click", () => this.close());
    document.getElementById("btn-preview-reload").addEventListener("click", () => this.load());
  }

  /** @returns {boolean} the preview is shown. */
  get isOpen() {
    return !this.wrap.hidden;
  }

  /** Show or hide the preview. */
  toggle() {
    if (this.isOpen) this.close();
    else this.open();
  }

  /**
   * Show the preview with the current show.
   * @param {{job_id: string, run?: number}} [run] a Monte-Carlo run, or a simulation job's flight, to play instead
   * @param {number|null} [startTime] where that flight starts playing (s; its closest pair), else from the start
   */
  async open(run, startTime = null) {
    this.wrap.hidden = false;
    this.button.setAttribute("aria-pressed", "true");
    this._layout();
    await this.load(run, startTime);
  }

  /** Hide the preview. */
  close() {
    this._unwatchSheet();
    this.wrap.hidden = true;
    this.button.setAttribute("aria-pressed", "false");
    this._layout();
  }

  /**
   * Fold viser's bottom sheet to its handle strip once per sheet, so the scene shows.
   *
   * Why: the pane (265-400 px) is narrower than viser's mobile breakpoint (viser 1.1.1, client/src/App.tsx:
   * `(max-width: ${theme.breakpoints.xs})`, Mantine's xs = 36em = 576 px), where viser lays its control panel
   * out as a bottom sheet up to 60% of the page tall, over the scene, and ignores the server's
   * `main_panel.minimize()`. Laying the page out wider instead (desktop layout, panel minimised) unmounts the
   * panel's contents, among them the link element `viewerState` reads the shared playhead from; a folded sheet
   * keeps them (a Mantine Collapse). A sheet the designer unfolds stays unfolded; a new one (a new page, a
   * re-mount) is folded again.
   */
  /**
   * Watch the viewer page now in the frame for viser's bottom sheet: a MutationObserver on its body (elements
   * added or removed anywhere below it; a playing show's readouts change text, not elements), each frame's
   * changes looked at once. Nothing runs while the page does not change, and nothing once the preview is closed.
   */
  _watchSheet() {
    this._unwatchSheet();
    if (!this.isOpen) return;
    let doc = null;
    try {
      doc = this.frame.contentDocument;
    } catch {
      return;
    }
    if (!doc || !doc.body) return;
    this.foldSheet();
    this.sheetWatch = new MutationObserver(() => {
      if (this.foldDue) return;
      this.foldDue = true;
      requestAnimationFrame(() => {
        this.foldDue = false;
        this.foldSheet();
      });
    });
    this.sheetWatch.observe(doc.body, { childList: true, subtree: true });
  }

  _unwatchSheet() {
    if (this.sheetWatch !== null) this.sheetWatch.disconnect();
    this.sheetWatch = null;
  }

  foldSheet() {
    let doc = null;
    try {
      doc = this.frame.contentDocument;
    } catch {
      return;
    }
    // The sheet's handle (BottomPanel.Handle): the clickable 3.5em strip of a fixed panel at the bottom.
    const handle = doc && /** @type {HTMLElement|null} */ (doc.querySelector('div[style*="height: 3.5em"][style*="cursor: pointer"]'));
    if (!handle || handle.dataset.swarmshowFolded) return;
    const sheet = handle.closest('[style*="position: fixed"]');
    if (!sheet || !doc.getElementById("swarmshow-viewer")) return; // not the sheet, or its contents not there yet
    handle.dataset.swarmshowFolded = "1";
    handle.click();
  }

  _layout() {
    this.wrap.classList.toggle("over", this.over.checked);
    this.onLayout();
  }

  /**
   * The preview's own viewer playback, read from its page (same origin): the token that names it to
   * the server and where its playhead is. Null while the preview is closed or still connecting.
   * and which effect stack it paints (`lights`: the revision the lights endpoint answered, 0: the saved show's).
   * @returns {{token: string, time_s: number, phase: string, formation: number, playing: boolean, lights: number}|null}
   */
  viewerState() {
    if (!this.isOpen) return null;
    let el = null;
    try {
      el = this.frame.contentDocument && this.frame.contentDocument.getElementById("swarmshow-viewer");
    } catch {
      return null;
    }
    if (!el || !el.dataset.token) return null;
    return {
      token: el.dataset.token,
      time_s: Number(el.dataset.time),
      phase: el.dataset.phase || "none",
      formation: Number(el.dataset.formation),
      playing: el.dataset.playing === "1",
      lights: Number(el.dataset.lights || 0),
    };
  }

  /**
   * Save if needed, load the show into the viewer and (re)load the viewer page.
   * @param {{job_id: string, run?: number}} [run] a Monte-Carlo run of the show to fly and play (its
   *   simulated flight), or a simulation job's flight, instead of the planned or last simulated show
   * @param {number|null} [startTime] with `run`: the time the new page starts at (s), else from the start
   */
  async load(run, startTime = null) {
    setError("preview", "");
    const st = this.state;
    // The timeline and the preview share one playhead: a new page starts at the selected formation's hold
    // (the first formation: from the start, takeoff included); a Monte-Carlo run plays from the start.
    this.startFormation = run ? null : st.current;
    this.startTime = run && startTime != null ? startTime : null;
    // The last simulation's own flight (its preset and seed), not a default one, once there is one.
    if (!run && this.source() === "simulated") run = this.flight();
    if (st.meta) {
      if (!(await this.persist.ensureSaved())) {
        setError("preview", "The show could not be saved; the preview shows the last saved version.");
      }
      const draft = this.persist.draftRefusal("played in 3D");
      if (draft) setError("preview", draft);
      else try {
        const out = await api.loadPlayback(st.meta.id, run ? "simulated" : this.source(), run);
        // A transition forced shorter than the limits allow plays as designed (the viewer draws the
        // check's violations in red), but no drone could fly it: say so, as the exports will refuse it.
        const problems = (out && out.problems) || [];
        if (problems.length) {
          setError("preview", `Plays as designed, but cannot be flown: ${problems.map((p) => p.msg).join("; ")}. `
            + "The red marks show where; exports refuse the show until that is fixed.");
        }
      } catch (err) {
        setError("preview", `Cannot load the show into the 3D view: ${err.message}`);
      }
    }
    // A fresh viewer page: each page is its own viewer client and starts on the show just loaded
    // (other tabs' viewers keep theirs).
    this.frame.src = "/viser/";
  }
}
