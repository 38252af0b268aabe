// @ts-check
// The editor's entry point: builds the parts and wires them to the page.

import * as api from "./api.js";
import { CanvasView } from "./canvas.js";
import { applyColor, applyGradient, colorsFromImage, targetIndices } from "./colors.js";
import { askText, toast } from "./dialogs.js";
import { clearShowErrors, describe, formationProblems, setError, showShowErrors } from "./errors.js";
import { EffectsPanel } from "./effects.js";
import { EffectLane } from "./fxlane.js";
import { ExportMenu } from "./exportmenu.js";
import { flyingCount, GroupsPanel } from "./groups.js";
import { HistoryPanel } from "./history.js";
import { MotionPanel } from "./motion.js";
import { MusicLane } from "./music.js";
import { AXIS_NAMES, audiencePoint, faceAudienceDegrees, rotateAboutAxis, rotateInView, scaleAbout } from "./geometry.js";
import { Persistence } from "./persist.js";
import { Preview } from "./preview.js";
import { Playhead } from "./playhead.js";
import { ReportPanel } from "./report.js";
import { SettingsForm } from "./settings.js";
import { LaunchPanel } from "./launch.js";
import { installShortcuts, renderHelp } from "./shortcuts.js";
import { ShowsDialog } from "./shows.js";
import { SimulatePanel } from "./simulate.js";
import { Sources } from "./sources.js";
import { closePairs, roundKeepingSpacing } from "./spacing.js";
import { EditorState, durationProblem } from "./state.js";
import { Timeline } from "./timeline.js";
import { TOOLS, Tools } from "./tools.js";
import { keepUndoAcrossReloads } from "./undostore.js";

/** Element by id; `any` because the ids name inputs, buttons and panels alike. @type {(id: string) => any} */
const $ = (id) => document.getElementById(id);

const state = new EditorState();
keepUndoAcrossReloads(state);
const view = new CanvasView(/** @type {HTMLCanvasElement} */ ($("canvas")), state);
new MotionPanel(state, view);
const timeline = new Timeline(/** @type {HTMLOListElement} */ ($("timeline-list")), state);
timeline.problems = formationProblems;
timeline.onTransition = async (k) => {
  const f = state.show.formations[k];
  const min = timeline.minDurations[k];
  const text = await askText(
    `Transition into "${f.name}"`,
    `Duration in seconds${min != null ? ` (at least ${min.toFixed(1)})` : ""}; blank: as fast as the limits allow`,
    f.transition_s != null ? String(f.transition_s) : "",
    { allowBlank: true, validate: (t) => { const p = durationProblem(Number(t)); return p ? `The transition ${p}` : null; } },
  );
  if (text === null) return;
  const v = Number(text);
  const problem = durationProblem(v);
  if (text === "") timeline.setTransition(k, null);
  else if (!problem) timeline.setTransition(k, v);
  else toast(`The transition into "${f.name}" ${problem}`, { error: true });
};

function status(msg, error = false) {
  const el = $("save-status");
  el.textContent = msg;
  el.classList.toggle("error", error);
  el.title = msg;
}

const persist = new Persistence(state, { status, rendered: () => timeline.render() });
const tools = new Tools(view, state, {
  color: () => /** @type {HTMLInputElement} */ ($("color-pick")).value,
  onError: (msg) => status(msg, true),
});
const settingsForm = new SettingsForm(/** @type {HTMLFormElement} */ ($("form-settings")), state);
new LaunchPanel(/** @type {HTMLElement} */ ($("launch-body")), state);
const sources = new Sources(state, view);
settingsForm.fitAll = () => sources.fitAll();
const report = new ReportPanel($("report-body"), state, persist, { timeline, view });
const simulate = new SimulatePanel(state, persist, {
  onFlown: () => preview.isOpen && preview.load(),
  onPlayRun: (run, t) => (preview.isOpen ? preview.load(run, t) : preview.open(run, t)),
  onFormationProblems: () => timeline.render(),
  // Simulated without a check: the timeline shows the plan's transition lengths all the same.
  onPlanned: (plan) => {
    if (!state.show || simulate.startedVersion !== state.version) return;
    timeline.setPlanned(state.show.formations.length, plan);
    timeline.render();
  },
});
const preview = new Preview(state, persist, () => requestAnimationFrame(() => view.redraw()),
  () => (simulate.hasFlight ? "simulated" : "planned"), () => simulate.flight);
const playhead = new Playhead(state, timeline, preview);
const exportMenu = new ExportMenu(state, persist, { onFormationProblems: () => timeline.render() });
// The music lane (issue 18) places unpinned formations where the last check planned them.
/** @type {Promise<void>} the checks asked for by pins, one after the other */
let pinChecks = Promise.resolve();
const music = new MusicLane(state, {
  plan: () => (report.result ? report.result.plan : null),
  previewOpen: () => preview.isOpen,
  // The plan says whether the pinned time can be flown (its refusal lands on the formation's card).
  pinned: () => { pinChecks = pinChecks.then(() => report.run()); },
});
const renderReport = report.render.bind(report);
report.render = () => { renderReport(); music.draw(); };
const shows = new ShowsDialog(state, persist, opened);
new HistoryPanel($("history-body"), state);
const effects = new EffectsPanel($("effects-body"), state, {
  redraw: () => view.redraw(), toast,
  plan: () => (report.result ? report.result.plan : null),
  viewer: () => preview.viewerState(),
});
// Drone groups and who flies each formation (issue 21); a new group becomes the selected effect's target.
const groups = new GroupsPanel($("groups-body"), state, {
  toast,
  selectedDrones: () => effects.selectedDrones(),
  ask: (title, label, value) => askText(title, label, value),
  created: (name) => effects.targetGroup(name),
});
// The 3D preview paints the editor's unsaved effects: sent after each edit, and to a new viewer page
// (a reload or a fresh preview has a new token) within a second.
window.setInterval(() => { if (preview.isOpen && !document.hidden) effects.sendToViewer(); }, 1000);
// Effect bars on the music lane's time axis, redrawn with it (playhead, span).
const fxLane = new EffectLane(state, music, effects);
const drawMusic = music.draw.bind(music);
music.draw = () => { drawMusic(); fxLane.draw(); };
view.colorOverride = (f, base) => effects.colorsFor(f, base);

// ---- page state ------------------------------------------------------------------------------

function opened(rec) {
  clearShowErrors();
  // A stored draft: mark what is wrong on the cards and fields, as a refused save would.
  if (state.meta && state.meta.draft) {
    showShowErrors(state.meta.problems || [], () => {});
    timeline.render();
  }
  history.replaceState(null, "", rec ? `?show=${encodeURIComponent(rec.id)}` : location.pathname);
  refreshChrome();
  requestAnimationFrame(() => view.fit());
  if (rec) status(`Opened "${rec.name}" · revision ${rec.revision}`);
  else status("");
  if (preview.isOpen && rec) preview.load();
}
persist.addEventListener("draft", () => refreshChrome());
persist.addEventListener("opened", (/** @type {any} */ e) => {
  history.replaceState(null, "", `?show=${encodeURIComponent(e.detail.id)}`);
  refreshChrome();
  requestAnimationFrame(() => view.fit());
});

function refreshChrome() {
  const has = !!state.show;
  $("show-title").textContent = has ? state.show.name : "No show open";
  document.title = has ? `${state.dirty ? "• " : ""}${state.show.name} · swarmshow` : "swarmshow editor";
  $("dirty-indicator").hidden = !state.dirty;
  $("btn-save").disabled = !has;
  for (const id of ["btn-check", "btn-simulate", "btn-preview", "btn-export", "export-format"]) $(id).disabled = !has;
  const undo = /** @type {HTMLButtonElement} */ ($("btn-undo"));
  const redo = /** @type {HTMLButtonElement} */ ($("btn-redo"));
  undo.disabled = !state.undoStack.length;
  redo.disabled = !state.redoStack.length;
  const u = state.undoStack[state.undoStack.length - 1];
  const r = state.redoStack[state.redoStack.length - 1];
  undo.title = u ? `Undo ${u.label} (Ctrl+Z)` : "Undo (Ctrl+Z)";
  redo.title = r ? `Redo ${r.label} (Ctrl+Shift+Z)` : "Redo (Ctrl+Shift+Z)";
  undo.setAttribute("aria-label", u ? `Undo ${u.label}` : "Undo");
  redo.setAttribute("aria-label", r ? `Redo ${r.label}` : "Redo");
  $("empty-hint").hidden = has;
  renderDraft();
  updateStatusbar();
}

/** The draft badge and the list of what is wrong with the stored draft (hidden for a valid show). */
let draftShown = "";
function renderDraft() {
  const meta = state.show ? state.meta : null;
  const draft = !!(meta && meta.draft);
  $("draft-badge").hidden = !draft;
  $("draft-panel").hidden = !draft;
  const problems = draft ? meta.problems || [] : [];
  const key = JSON.stringify(problems);
  if (key === draftShown) return;
  draftShown = key;
  const list = $("draft-problems");
  list.replaceChildren();
  for (const p of problems) {
    const li = document.createElement("li");
    const b = document.createElement("button");
    b.type = "button";
    // In the designer's words; the server's own text stays at hand for an operator (the tooltip).
    const said = describe(p);
    b.textContent = `${said.where}: ${said.msg}`;
    b.title = said.raw;
    const m = /^formations\[(\d+)\]/.exec(p.path || "");
    if (m) {
      // Take the user to the formation the problem is in.
      b.addEventListener("click", () => state.setCurrent(Number(m[1])));
    } else {
      b.addEventListener("click", () => { /** @type {HTMLDetailsElement} */ ($("settings-panel")).open = true; });
    }
    li.append(b);
    list.append(li);
  }
}
$("draft-badge").addEventListener("click", () => {
  $("draft-panel").scrollIntoView({ block: "nearest" });
  const first = /** @type {HTMLElement|null} */ ($("draft-problems").querySelector("button"));
  if (first) first.focus();
});

let spacingQueued = false;
function updateSpacing() {
  if (spacingQueued) return;
  spacingQueued = true;
  requestAnimationFrame(() => {
    spacingQueued = false;
    const f = state.formation;
    const r = f ? closePairs(f.points, state.show.settings.min_distance_m) : { close: new Set(), pairs: [], minDistance: Infinity };
    view.close = r.close;
    const el = $("st-spacing");
    // Points below the altitude floor (or underground) are a problem the spacing tick must not hide.
    const floor = f ? state.show.settings.min_altitude_m ?? 2.5 : 0;
    let low = 0;
    let lowest = Infinity;
    for (const p of f ? f.points : []) {
      if (p[2] < floor) low++;
      if (p[2] < lowest) lowest = p[2];
    }
    const lowText = low ? `${low} point${low > 1 ? "s" : ""} below ${lowest < 0 ? "the ground" : `the ${floor} m floor`} (lowest ${lowest.toFixed(1)} m): raise by ${(floor - lowest).toFixed(1)} m` : "";
    if (!f) el.textContent = "";
    else if (r.pairs.length) {
      el.textContent = `${r.close.size} points closer than ${state.show.settings.min_distance_m} m (closest ${r.minDistance.toFixed(2)} m): Repair spacing${lowText ? ` · ${lowText}` : ""}`;
      el.className = "bad";
    } else if (low) {
      el.textContent = lowText;
      el.className = "bad";
    } else {
      el.textContent = `spacing ≥ ${state.show.settings.min_distance_m} m ✓`;
      el.className = "";
    }
    el.title = el.textContent;
    view.redraw();
  });
}

function updateStatusbar() {
  const f = state.formation;
  const pts = $("st-points");
  if (!f) {
    pts.textContent = "";
    $("st-selection").textContent = "";
    return;
  }
  const n = flyingCount(state.show, f);
  const m = f.points.length;
  pts.textContent = `"${f.name}": ${m} points / ${n} drones${m < n ? ` (need ${n - m} more: Fit to N drones)` : m > n ? ` (${m - n} stay dark)` : ""}`;
  pts.className = m < n ? "bad" : "";
  $("st-selection").textContent = state.selection.size ? `${state.selection.size} selected` : "";
}

state.addEventListener("change", (/** @type {any} */ e) => {
  const kind = e.detail.kind;
  // A refused save's message is about the document before this edit: do not leave it on screen.
  if (kind === "edit" && $("save-status").classList.contains("error")) status(state.dirty ? "Unsaved changes" : "");
  if (kind !== "live") refreshChrome();
  else updateStatusbar();
  if (kind === "load" || kind === "current") view.flagged = new Set();
  // Another formation may sit elsewhere or be another size: show it whole.
  if (kind === "current") requestAnimationFrame(() => view.fit());
  updateSpacing();
  view.redraw();
});

view.onCursor = ([u, v]) => {
  if (view.is3d) {
    $("st-cursor").textContent = "3D view";
    return;
  }
  const names = { front: ["x", "z"], top: ["x", "y"], side: ["y", "z"] }[view.view] || ["x", "z"];
  $("st-cursor").textContent = `${names[0]} ${u.toFixed(1)} m  ${names[1]} ${v.toFixed(1)} m`;
};

// ---- controls --------------------------------------------------------------------------------

// The formation sources are an accordion: opening one closes the others (the sidebar stays short).
const sourcePanels = /** @type {HTMLDetailsElement[]} */ ([...document.querySelectorAll("details.source-panel")]);
for (const d of sourcePanels) {
  d.addEventListener("toggle", () => {
    if (d.open) for (const other of sourcePanels) if (other !== d) other.open = false;
  });
}

function setTool(tool) {
  tools.setTool(tool);
  for (const b of document.querySelectorAll(".tool")) b.setAttribute("aria-checked", String(/** @type {HTMLElement} */ (b).dataset.tool === tool));
}
for (const b of document.querySelectorAll(".tool")) b.addEventListener("click", () => setTool(/** @type {HTMLElement} */ (b).dataset.tool));
setTool("select");

const viewSelect = /** @type {HTMLSelectElement} */ ($("view-select"));
viewSelect.addEventListener("change", () => {
  view.setView(/** @type {"front"|"top"|"side"|"3d"} */ (viewSelect.value));
  // New points go at the formation's typical depth: its median y (front), altitude (top) or x (side).
  const axis = view.axes[2];
  const values = (state.formation ? state.formation.points : []).map((p) => p[axis]).sort((a, b) => a - b);
  view.depth = values.length ? Math.round(values[Math.floor(values.length / 2)] * 10) / 10 : axis === 2 ? 40 : 0;
  const depth = /** @type {HTMLInputElement} */ ($("depth-input"));
  depth.value = String(view.depth);
  // Named as the canvas' legend names the axes; the 3D view has no drawing plane (Draw and Place are refused
  // there), so no depth for new points either.
  const what = `${axis === 2 ? "Altitude" : "Depth"} ${AXIS_NAMES[axis]}`;
  depth.setAttribute("aria-label", `${what} of new points, metres`);
  $("depth-label").textContent = `${what}, m`;
  $("depth-row").hidden = view.is3d;
});
$("move-axis").addEventListener("change", (e) => {
  tools.moveAxis = /** @type {"free"|"x"|"y"|"z"} */ (/** @type {HTMLSelectElement} */ (e.target).value);
});

// Rotations in 3D: about x, y or z through the selection's (or formation's) centre, and the turn
// about the vertical that faces the formation to the audience.
$("btn-rotate-axis").addEventListener("click", () => {
  setError("transform", "");
  const deg = Number(/** @type {HTMLInputElement} */ ($("rotate-axis-deg")).value);
  const axis = /** @type {0|1|2} */ (Number(/** @type {HTMLSelectElement} */ ($("rotate-axis")).value));
  if (!state.formation) return;
  if (!Number.isFinite(deg)) {
    setError("transform", "The rotation must be a number of degrees.");
    return;
  }
  const idx = targetIndices(state);
  state.edit(`Rotate ${+deg.toFixed(3)}° about ${"xyz"[axis]}`, () => {
    rotateAboutAxis(state.formation.points, idx, axis, deg);
    state.formation.points = roundKeepingSpacing(state.formation.points, state.show.settings.min_distance_m, idx);
  });
});
$("btn-face-audience").addEventListener("click", () => {
  setError("transform", "");
  const f = state.formation;
  if (!f || !f.points.length) return;
  const idx = f.points.map((_, i) => i);
  const deg = faceAudienceDegrees(f.points, idx, audiencePoint(state.show));
  if (deg === 0) {
    toast("The formation already faces the audience");
    return;
  }
  state.edit("Face the audience", () => {
    rotateAboutAxis(state.formation.points, idx, 2, deg);
    state.formation.points = roundKeepingSpacing(state.formation.points, state.show.settings.min_distance_m);
  });
});
$("btn-fit-view").addEventListener("click", () => view.fit());
$("depth-input").addEventListener("change", (e) => { view.depth = Number(/** @type {HTMLInputElement} */ (e.target).value) || 0; });

/**
 * Undo or redo, and forget the planned transition durations of the last check: they belong to
 * the document before the step (the next check plans them again).
 * @param {"undo"|"redo"} which
 */
function undoRedo(which) {
  if (!(which === "undo" ? state.undo() : state.redo())) return;
  timeline.setCheck(state.show.formations.length, [], []);
  timeline.render();
}
$("btn-undo").addEventListener("click", () => undoRedo("undo"));
$("btn-redo").addEventListener("click", () => undoRedo("redo"));
$("btn-save").addEventListener("click", () => persist.save({ force: !state.dirty }));
const autosave = /** @type {HTMLInputElement} */ ($("chk-autosave"));
autosave.checked = persist.autosave;
autosave.addEventListener("change", () => persist.setAutosave(autosave.checked));
$("btn-shows").addEventListener("click", () => shows.open());
$("btn-check").addEventListener("click", () => report.run());
$("btn-simulate").addEventListener("click", () => simulate.run());
$("btn-preview").addEventListener("click", () => preview.toggle());
$("btn-add-formation").addEventListener("click", () => timeline.add());
$("btn-dup-formation").addEventListener("click", () => timeline.duplicate());
$("btn-del-formation").addEventListener("click", () => {
  setError("formations", timeline.remove() === false && state.show ? "A show needs at least one formation." : "");
});

$("btn-apply-color").addEventListener("click", () => applyColor(state, /** @type {HTMLInputElement} */ ($("color-pick")).value));
$("btn-gradient").addEventListener("click", () => applyGradient(state, $("grad-a").value, $("grad-b").value, $("grad-axis").value, view.view));
$("color-image").addEventListener("change", async (e) => {
  const input = /** @type {HTMLInputElement} */ (e.target);
  const file = input.files && input.files[0];
  input.value = "";
  setError("colors", "");
  if (!file || !state.formation) return;
  try {
    const n = await colorsFromImage(state, file, view.view);
    toast(n ? `Coloured ${n} points from ${file.name}` : `${file.name} is transparent over these points`);
  } catch (err) {
    setError("colors", err.message);
  }
});

// Help dialog and shortcuts.
const helpDlg = /** @type {HTMLDialogElement} */ ($("dlg-help"));
$("btn-help").addEventListener("click", () => helpDlg.showModal());
$("btn-help-close").addEventListener("click", () => helpDlg.close());

function nudge(e) {
  const idx = [...state.selection];
  if (!idx.length) return;
  const step = e.shiftKey ? 5 : e.altKey ? 0.1 : 1;
  let [a, b] = view.axes;
  let [sa, sb] = [1, 1];
  if (view.is3d) {
    // Along the world axes nearest the screen's right and up, signed so the arrows match the screen.
    const { right, up } = view.camera.frame();
    a = [0, 1, 2].reduce((m, k) => (Math.abs(right[k]) > Math.abs(right[m]) ? k : m), 0);
    b = [0, 1, 2].filter((k) => k !== a).reduce((m, k) => (Math.abs(up[k]) > Math.abs(up[m]) ? k : m));
    sa = Math.sign(right[a]) || 1;
    sb = Math.sign(up[b]) || 1;
  }
  const d = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, step], ArrowDown: [0, -step] }[e.key];
  state.edit(`Nudge ${idx.length} points`, () => {
    const pts = state.formation.points;
    for (const i of idx) {
      pts[i][a] += sa * d[0];
      pts[i][b] += sb * d[1];
    }
    state.formation.points = roundKeepingSpacing(pts, state.show.settings.min_distance_m, idx);
  });
}

const shortcuts = installShortcuts({
  save: () => persist.save({ force: !state.dirty }),
  undo: () => undoRedo("undo"),
  redo: () => undoRedo("redo"),
  shows: () => shows.open(),
  check: () => state.show && report.run(),
  exportNow: () => state.show && exportMenu.run(),
  preview: () => state.show && preview.toggle(),
  tool: setTool,
  toggleView: () => {
    viewSelect.value = view.view === "front" ? "top" : "front";
    viewSelect.dispatchEvent(new Event("change"));
  },
  toggleView3d: () => {
    viewSelect.value = view.view === "side" ? "3d" : "side";
    viewSelect.dispatchEvent(new Event("change"));
  },
  fit: () => view.fit(),
  selectAll: () => state.formation && state.setSelection(state.formation.points.map((_, i) => i)),
  escape: () => {
    tools.cancel();
    if (state.selection.size) state.setSelection([]);
    view.flagged = new Set();
    view.redraw();
  },
  deleteSelection: () => {
    const idx = new Set(state.selection);
    if (!idx.size || !state.formation) return;
    state.edit(`Delete ${idx.size} point${idx.size > 1 ? "s" : ""}`, () => {
      const f = state.formation;
      f.points = f.points.filter((_, i) => !idx.has(i));
      f.colors = f.colors.filter((_, i) => !idx.has(i));
      state.selection = new Set();
    });
  },
  addFormation: () => timeline.add(),
  duplicate: () => timeline.duplicate(),
  help: () => (helpDlg.open ? helpDlg.close() : helpDlg.showModal()),
  keyed: (e) => {
    if (!state.show) return;
    if (e.key === "+" || e.key === "=") view.zoom(1.25);
    else if (e.key === "-" || e.key === "_") view.zoom(0.8);
    else if (e.altKey && (e.key === "ArrowLeft" || e.key === "ArrowRight")) {
      timeline.move(state.current, state.current + (e.key === "ArrowLeft" ? -1 : 1));
    } else if (e.key.startsWith("Arrow")) nudge(e);
    else if (e.key === "PageUp") state.setCurrent(state.current - 1);
    else if (e.key === "PageDown") state.setCurrent(state.current + 1);
    else if (e.key === "[" || e.key === "]") {
      const idx = targetIndices(state);
      state.edit("Rotate 5°", () => {
        rotateInView(state.formation.points, idx, e.key === "[" ? 5 : -5, view.view);
        state.formation.points = roundKeepingSpacing(state.formation.points, state.show.settings.min_distance_m, idx);
      });
    } else if (e.key === "<" || e.key === ">") {
      const idx = targetIndices(state);
      state.edit(e.key === ">" ? "Grow 10%" : "Shrink 10%", () => {
        scaleAbout(state.formation.points, idx, e.key === ">" ? 1.1 : 1 / 1.1);
        state.formation.points = roundKeepingSpacing(state.formation.points, state.show.settings.min_distance_m, idx);
      });
    }
  },
});
renderHelp(/** @type {HTMLTableElement} */ ($("help-table")), shortcuts);

// Token prompt (servers bound beyond loopback ask for one).
api.setTokenPrompt(() => new Promise((resolve) => {
  const dlg = /** @type {HTMLDialogElement} */ ($("dlg-token"));
  const form = $("form-token");
  const onSubmit = (e) => {
    e.preventDefault();
    dlg.close();
    resolve(/** @type {HTMLInputElement} */ ($("token-input")).value.trim() || null);
  };
  form.addEventListener("submit", onSubmit, { once: true });
  dlg.addEventListener("cancel", () => resolve(null), { once: true });
  dlg.showModal();
}));

// ---- start -----------------------------------------------------------------------------------

async function start() {
  refreshChrome();
  exportMenu.load().catch(() => {});
  const wanted = new URLSearchParams(location.search).get("show") || localStorage.getItem("swarmshow.last");
  if (wanted) await shows.openShow(wanted).catch(() => {});
  if (!state.show) {
    localStorage.removeItem("swarmshow.last");
    await shows.open();
  }
}

/** @type {any} */ (window).swarmshow = { state, view, tools, persist, TOOLS, music, playhead, effects, fxLane, report, groups };
start();
