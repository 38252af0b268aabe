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

const AXES = ["x", "y", "z"];
/** A field's unit suffix in words (formations/_show.py, _UNITS): 'hold_s' -> 'hold (s)'. */
const UNITS = { s: "s", m: "m", mps: "m/s", mps2: "m/s²", mps3: "m/s³", deg: "°", rad: "rad", hz: "Hz" };
const NAMED_LISTS = { formations: "formation", points: "point", colors: "colour", lights: "light", home: "home position", effects: "light effect" };
/** Objects that hold one named list and add nothing when a field follows ('lights.effects[0]': 'light effect 1'). */
const SILENT_PARENTS = new Set(["lights"]);

/** @param {string} key a field name -> in words, its unit in brackets ('max_accel_mps2' -> 'max accel (m/s²)') */
function plainKey(key) {
  const i = key.lastIndexOf("_");
  const unit = i > 0 ? UNITS[key.slice(i + 1)] : undefined;
  return unit ? `${key.slice(0, i).replace(/_/g, " ")} (${unit})` : key.replace(/_/g, " ");
}

/** @param {string} key a key with no index after it: a list's name as it is ('points'), any other field in words */
function saidAlone(key) {
  return key in NAMED_LISTS ? key.replace(/_/g, " ") : plainKey(key);
}

/**
 * A show file path in the designer's words, as the server's plain_path (formations/_show.py) says it:
 * 'formations[1].points[5][2]' -> 'formation 2 "Heart", point 6, z' (from 1, as people count; the formation
 * named when `show` has it).
 * @param {string} path @param {any} [show]
 * @returns {string}
 */
export function plainPath(path, show) {
  const words = [];
  let last = "";
  let pending = ""; // the last key, said when no index follows it
  let node = show;
  for (const [, key, index] of path.matchAll(/([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]/g)) {
    if (key) {
      if (pending && !SILENT_PARENTS.has(pending)) words.push(saidAlone(pending));
      last = pending = key;
      node = node && typeof node === "object" && !Array.isArray(node) ? node[key] : undefined;
      continue;
    }
    pending = "";
    const i = Number(index);
    node = Array.isArray(node) ? node[i] : undefined;
    if (last === "points" && words.length && words[words.length - 1].startsWith("point ")) {
      words.push(AXES[i] ?? `coordinate ${i + 1}`);
      continue;
    }
    let label = `${NAMED_LISTS[last] ?? last.replace(/_/g, " ")} ${i + 1}`;
    if (last === "formations" && node && typeof node.name === "string") label += ` "${node.name}"`;
    words.push(label);
  }
  if (pending) words.push(saidAlone(pending));
  return words.join(", ");
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
 * A problem as the designer reads it: where (a settings field by its label, a formation by number and name,
 * else the server's `where` or the path in words, as the server says them), what (plainMsg), and the server's own text
 * for an operator (`raw`).
 * @param {{path?: string, msg: string, where?: string}} p @param {any} [show]
 * @returns {{where: string, msg: string, raw: string}}
 */
export function describe(p, show) {
  const path = p.path || "";
  const input = path && typeof document !== "undefined" && document.querySelector(`#form-settings [data-path="${CSS.escape(path)}"]`);
  const label = input && input.id ? document.querySelector(`label[for="${CSS.escape(input.id)}"]`) : null;
  const where = label ? label.textContent.trim() : p.where || plainPath(path, show) || "the show";
  const msg = namesPath(p.msg, path) ? p.msg.slice(path.length).replace(/^[:\s]+/, "") : p.msg;
  return { where, msg: plainMsg(msg), raw: path && !namesPath(p.msg, path) ? `${path}: ${p.msg}` : p.msg };
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
      // On the formation's own card: where in it ("hold (s)", "point 2, z") and the rule in words.
      const where = m[2] && !namesPath(p.msg, path) ? `${plainPath(m[2])}: ` : "";
      if (!formationProblems.has(k)) formationProblems.set(k, `${where}${plainMsg(p.msg)}`);
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
