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

/** pydantic's phrasing of a rule -> the editor's (the editor's own checks say "at least 0.1" too). */
/** @type {[RegExp, string][]} */
const PLAIN_RULES = [
  [/^Input should be greater than or equal to (.+)$/, "must be at least $1"],
  [/^Input should be greater than (.+)$/, "must be more than $1"],
  [/^Input should be less than or equal to (.+)$/, "must be at most $1"],
  [/^Input should be less than (.+)$/, "must be less than $1"],
  [/^Input should be a valid integer.*$/, "must be a whole number"],
  [/^Input should be a finite number$/, "must be a number"],
  [/^Input should be a valid number.*$/, "must be a number"],
  [/^Input should be a valid string$/, "must be text"],
  [/^Field required$/, "is missing"],
  [/^List should have at least (\d+) items? after validation.*$/, "needs at least $1"],
  [/^List should have at most (\d+) items? after validation.*$/, "takes at most $1"],
  [/^String should have at least (\d+) characters?$/, "needs at least $1 characters"],
  [/^String should have at most (\d+) characters?$/, "takes at most $1 characters"],
  [/^Extra inputs are not permitted$/, "is not part of a show file"],
  [/^Value error, (.+)$/, "$1"],
];

/** @param {string} msg a server message -> in the editor's words (unchanged when not a pydantic phrase) */
export function plainMsg(msg) {
  for (const [re, words] of PLAIN_RULES) {
    if (re.test(msg)) return msg.replace(re, words);
  }
  return msg;
}

/**
 * A problem as the designer reads it: where (a settings field by its label, else the server's `where`: the
 * path in the designer's words, formations by number and name, worded on the server, formations/_show.py
 * plain_words), what (plainMsg), and the server's own text for an operator (`raw`).
 * @param {{path?: string, msg: string, where?: string|null}} p
 * @returns {{where: string, msg: string, raw: string}}
 */
export function describe(p) {
  const path = p.path || "";
  const input = path && typeof document !== "undefined" && document.querySelector(`#form-settings [data-path="${CSS.escape(path)}"]`);
  const label = input && input.id ? document.querySelector(`label[for="${CSS.escape(input.id)}"]`) : null;
  const where = label ? label.textContent.trim() : p.where || path || "the show";
  const msg = namesPath(p.msg, path) ? p.msg.slice(path.length).replace(/^[:\s]+/, "") : p.msg;
  return { where, msg: plainMsg(msg), raw: path && !namesPath(p.msg, path) ? `${path}: ${p.msg}` : p.msg };
}

/**
 * A formation's problem as its own card says it: where in the formation in the server's words
 * (`where_in_formation`: "hold (s)", "point 2, z"; the card names the formation) and the rule in words. A
 * message that starts with its own path ("formations[1].arrive_at_s = 4 s is too early ...") says those words
 * in its place.
 * @param {{msg: string, where_in_formation?: string|null}} p @param {string} path @param {string} inner the path
 *   below the formation ("" for the formation itself)
 * @returns {string}
 */
function onCard(p, path, inner) {
  const words = inner ? p.where_in_formation || inner : "";
  if (namesPath(p.msg, path)) return words ? `${words}${p.msg.slice(path.length)}` : p.msg;
  return `${words ? `${words}: ` : ""}${plainMsg(p.msg)}`;
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
 * @param {{path: string, msg: string, where?: string|null, where_in_formation?: string|null}[]} problems
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
      if (!formationProblems.has(k)) formationProblems.set(k, onCard(p, path, m[2]));
      formations.push(k);
      continue;
    }
    const said = describe(p);
    if (path.startsWith("lights") && setError("lights", `${said.where}: ${said.msg}`)) {
      // Light effects (issue 18): shown in the effects panel with the effect's path.
      const panel = /** @type {HTMLDetailsElement|null} */ (document.getElementById("effects-panel"));
      if (panel) panel.open = true;
      continue;
    }
    if (path.startsWith("groups") && setError("groups", `${said.where}: ${said.msg}`)) continue;
    const input = document.querySelector(`#form-settings [data-path="${CSS.escape(path)}"]`);
    if (input) input.classList.add("has-error");
    // The most specific error slot: "home.grid.spacing_m", else "home.grid", else "home".
    const parts = path.split(".");
    let shown = false;
    while (parts.length && !shown) {
      shown = setError(parts.join("."), said.msg);
      parts.pop();
    }
    if (shown) {
      const panel = /** @type {HTMLDetailsElement|null} */ (
        document.getElementById(path.startsWith("home.boxes") ? "launch-panel" : "settings-panel"));
      if (panel && path !== "formations") panel.open = true;
    } else {
      fallback(path ? `${said.where}: ${said.msg}` : said.msg);
    }
  }
  return formations;
}
