// @ts-check
// API problems shown next to the control they concern: settings fields, timeline cards, or a
// fallback message element.

/**
 * Whether a problem's message starts by naming its own path ("path: ..." or "path = ...").
 * @param {string} msg
 * @param {string} path
 * @returns {boolean}
 */
export function namesPath(msg, path) {
  return msg.startsWith(`${path}:`) || msg.startsWith(`${path} `);
}

/** Formation problems by index, read by the timeline when it renders. */
export const formationProblems = new Map();

/** Remove every field error shown for the show document. */
export function clearShowErrors() {
  for (const el of document.querySelectorAll("#form-settings [data-error-for], .timeline [data-error-for], #effects-panel [data-error-for], #groups-panel [data-error-for]")) el.textContent = "";
  for (const el of document.querySelectorAll("#form-settings .has-error")) el.classList.remove("has-error");
  formationProblems.clear();
}

/**
 * Put an error message into the `[data-error-for=key]` element (empty string clears it).
 * @param {string} key
 * @param {string} message
 * @returns {boolean} whether such an element exists
 */
export function setError(key, message) {
  const el = document.querySelector(`[data-error-for="${CSS.escape(key)}"]`);
  if (!el) return false;
  el.textContent = message;
  return true;
}

/**
 * Show the problems of a rejected show next to the settings field or formation they name.
 * @param {{path: string, msg: string}[]} problems
 * @param {(msg: string) => void} fallback for problems not tied to a visible control
 * @returns {number[]} formation indices that have a problem
 */
export function showShowErrors(problems, fallback) {
  const formations = [];
  for (const p of problems) {
    const path = p.path || "";
    const m = /^formations\[(\d+)\]\.?(.*)$/.exec(path);
    if (m) {
      const k = Number(m[1]);
      const where = m[2] && !namesPath(p.msg, path) ? `${m[2]}: ` : "";
      if (!formationProblems.has(k)) formationProblems.set(k, `${where}${p.msg}`);
      formations.push(k);
      continue;
    }
    if (path.startsWith("lights") && setError("lights", `${path.replace(/^lights\.?/, "")}: ${p.msg}`)) {
      // Light effects (issue 18): shown in the effects panel with the effect's path.
      const panel = /** @type {HTMLDetailsElement|null} */ (document.getElementById("effects-panel"));
      if (panel) panel.open = true;
      continue;
    }
    if (path.startsWith("groups") && setError("groups", `${path.replace(/^groups\.?/, "")}: ${p.msg}`)) continue;
    const input = document.querySelector(`#form-settings [data-path="${CSS.escape(path)}"]`);
    if (input) input.classList.add("has-error");
    // The most specific error slot: "home.grid.spacing_m", else "home.grid", else "home".
    const parts = path.split(".");
    let shown = false;
    while (parts.length && !shown) {
      shown = setError(parts.join("."), p.msg);
      parts.pop();
    }
    if (shown) {
      const panel = /** @type {HTMLDetailsElement|null} */ (
        document.getElementById(path.startsWith("home.boxes") ? "launch-panel" : "settings-panel"));
      if (panel && path !== "formations") panel.open = true;
    } else {
      fallback(path ? `${path}: ${p.msg}` : p.msg);
    }
  }
  return formations;
}
