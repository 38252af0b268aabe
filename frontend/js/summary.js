// @ts-check
// A summary's pieces, shared by the check report and the flight and Monte-Carlo summaries: numbers
// formatted for reading, and the ✓/✗ heading with its two-column table.

/**
 * A number for reading: fixed digits and a unit, or "—" when there is none (null, NaN, ±Infinity).
 * @param {number|null|undefined} v @param {number} [digits] @param {string} [unit]
 * @returns {string}
 */
export function fmt(v, digits = 2, unit = "") {
  return v == null || !Number.isFinite(v) ? "—" : `${Number(v).toFixed(digits)}${unit}`;
}

/**
 * A check report's row for one limit: the value against it, and whether it breaks it. A value of null is none
 * to report (`min_distance_m` of a one-drone show: no pair), said in `none` and never drawn as breaking the limit.
 * @param {string} label @param {number|null|undefined} v @param {number|null|undefined} lim
 * @param {string} unit @param {"min"|"max"} sense @param {string} [none] the text for no value
 * @returns {[string, string, boolean]}
 */
export function limitRow(label, v, lim, unit, sense, none = "—") {
  const has = v != null && Number.isFinite(v);
  const bad = lim != null && has && (sense === "min" ? v < lim - 1e-9 : v > lim + 1e-9);
  const value = has ? `${fmt(v)} ${unit}` : none;
  return [label, `${value}${lim != null ? ` (${sense === "min" ? "≥" : "≤"} ${fmt(lim, 1)})` : ""}`, bad];
}

/**
 * A check group's minimum distance for ordering: the number, or Infinity when there is none (null: no pair,
 * e.g. a one-drone show; older reports said -1). `null >= 0` is true in JavaScript, so a plain `>= 0` test
 * ordered "no pair" as a distance of 0, worst of all.
 * @param {number|null|undefined} v
 * @returns {number}
 */
export function distanceForOrder(v) {
  return typeof v === "number" && Number.isFinite(v) && v >= 0 ? v : Infinity;
}

/**
 * A check group's closest-pair text for its title: ", closest 3.20 m", or ", no pair" when there is none.
 * @param {number|null|undefined} v the group's `min_distance_m`
 * @returns {string}
 */
export function closestText(v) {
  return Number.isFinite(distanceForOrder(v)) ? `, closest ${fmt(v)} m` : ", closest: none (no pair)";
}

/** How the planner flew a transition (``TransitionInfo.resolution`` in sim.plan), in plain words. */
const PLANNER_TEXT = {
  none: "Every drone flies a straight line, all of them together.",
  delays: "Straight lines; some drones leave later or fly slower so that every pair keeps its distance.",
  layers: "The formations are spread apart, crossed and contracted again so that every pair keeps its distance.",
  unresolved: "The planner could not make every pair keep its distance (see below).",
};

/**
 * The check report's line on how the planner flew a transition ("Planner: none." read as if no planner ran).
 * @param {string} resolution the report group's `resolution` ("" when the planner did not say)
 * @returns {string} a sentence, or "" when there is nothing to say
 */
export function plannerText(resolution) {
  if (!resolution) return "";
  return Object.hasOwn(PLANNER_TEXT, resolution) ? PLANNER_TEXT[resolution] : `Planner: ${resolution}.`;
}

/**
 * A summary's heading (the ✓ or ✗ line) and its two-column table, as the check report and
 * the flight and Monte-Carlo summaries show them.
 * @param {boolean} ok whether the heading reads as a pass
 * @param {string} text the heading
 * @param {string} label the table's accessible name
 * @param {Array<[string, string, boolean?] | null | false | undefined>} rows label, value and whether
 *   the value breaks a limit (drawn as bad); falsy rows are left out
 * @returns {[HTMLParagraphElement, HTMLTableElement]}
 */
export function summaryTable(ok, text, label, rows) {
  const head = document.createElement("p");
  head.className = ok ? "report-ok" : "report-bad";
  head.textContent = text;
  const table = document.createElement("table");
  table.setAttribute("aria-label", label);
  for (const r of rows) {
    if (!r) continue;
    const [name, value, bad] = r;
    const tr = document.createElement("tr");
    const a = document.createElement("td");
    a.textContent = name;
    const b = document.createElement("td");
    b.textContent = value;
    if (bad) b.className = "bad-value";
    tr.append(a, b);
    table.append(tr);
  }
  return [head, table];
}
