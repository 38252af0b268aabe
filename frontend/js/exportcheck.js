// @ts-check
// What the editor can tell about an export before asking the server (no DOM, run under node --test):
// the typed origin's syntax and ranges (the show file's settings.geo bounds) and the formats that need it.

/** Formats that place the show on Earth and refuse a show without an origin (app.exports, _qgc.py). */
export const GEO_FORMATS = ["qgc-plan", "qgc-wpl"];
/** The origin altitude's range, metres (formations.MIN_ORIGIN_ALT_M / MAX_ORIGIN_ALT_M; a test keeps them equal). */
export const MIN_ORIGIN_ALT_M = -1000;
export const MAX_ORIGIN_ALT_M = 10000;

/**
 * The origin field's text as numbers, or why it cannot be one.
 * @param {string} text "lat, lon[, alt m]"
 * @returns {{value: [number, number, number], error: ""} | {value: null, error: string}}
 */
export function parseOrigin(text) {
  const v = String(text).split(/[,\s]+/).filter(Boolean).map(Number);
  if (v.length < 2 || v.length > 3 || !v.every(Number.isFinite)) {
    return { value: null, error: "Origin: latitude, longitude (degrees) and optionally altitude (m), e.g. 47.3977, 8.5456, 410" };
  }
  if (Math.abs(v[0]) > 90) return { value: null, error: `Origin: latitude must be in [-90, 90] degrees, got ${v[0]}` };
  if (Math.abs(v[1]) > 180) return { value: null, error: `Origin: longitude must be in [-180, 180] degrees, got ${v[1]}` };
  const alt = v[2] ?? 0;
  if (alt < MIN_ORIGIN_ALT_M || alt > MAX_ORIGIN_ALT_M) {
    return { value: null, error: `Origin: altitude must be in [${MIN_ORIGIN_ALT_M}, ${MAX_ORIGIN_ALT_M}] m above sea level, got ${alt}` };
  }
  return { value: [v[0], v[1], alt], error: "" };
}

/**
 * Why `format` cannot be exported from a show placed at `geo` (its settings.geo) with the trajectories `source`,
 * "" when it can as far as the editor knows: the QGroundControl formats need the show's origin, and only the
 * formats in FLOWN_FORMATS hold the simulated (flown) trajectories (the server refuses the others with 422).
 * @param {string} format
 * @param {object|null|undefined} geo
 * @param {string} [source] "planned" (default) or "simulated"
 * @returns {string}
 */
export function exportProblem(format, geo, source = "planned") {
  if (GEO_FORMATS.includes(format) && !geo) {
    return "needs the show's place on Earth: enter its origin (latitude, longitude, altitude) "
      + "in Export options → Origin first.";
  }
  if (source === "simulated" && !FLOWN_FORMATS.includes(format)) {
    return "exports the exact plan, not the simulated flight: set Export options → Trajectories to planned, "
      + `or choose ${FLOWN_FORMATS.join(", ")}.`;
  }
  return "";
}

/** Formats that apply the scale and offset (indoor flying), and formats that can hold the flown trajectories
 * (app.exports SCALING_FORMATS / FLOWN_FORMATS; a test keeps them equal). The server refuses an option a format
 * does not take, so the editor sends it only where it is used. */
export const SCALING_FORMATS = ["crazyswarm"];
export const FLOWN_FORMATS = ["skybrush-csv", "waypoints-csv", "viser-html"];
/** Formats that sample the trajectories at a rate (app.exports SAMPLED_FORMATS): the others refuse `fps`. */
export const SAMPLED_FORMATS = ["skybrush-csv", "waypoints-csv", "viser-html"];

/**
 * The query options of an export of `format`: the export fields the format takes (blank and default ones left
 * out) and, for the flown trajectories, the simulation panel's preset, seed, controller and (with preset
 * "ideal", the only one that takes it) disturbance, so that the file holds the single flight the designer chose
 * (the server flies the same one: sim.flight.single_flight_options).
 * @param {string} format
 * @param {{fps?: string, source?: string, scale?: string, offset?: string}} fields the export options' text
 * @param {{preset?: string, seed?: string, controller?: string, disturbance?: string}} flight the simulation
 *   panel's `#sim-preset`, `#sim-seed`, `#sim-controller` and `#sim-disturbance`
 * @returns {Record<string, string>}
 */
export function exportQuery(format, fields, flight = {}) {
  /** @type {Record<string, string>} */
  const out = {};
  const text = (/** @type {string|undefined} */ v) => String(v ?? "").trim().replace(/\s+/g, "");
  if (SAMPLED_FORMATS.includes(format) && text(fields.fps) !== "") out.fps = text(fields.fps);
  // Only a format that can hold the flown trajectories gets them (exportProblem says so for the others).
  if (text(fields.source) === "simulated" && FLOWN_FORMATS.includes(format)) {
    out.source = "simulated";
    if (text(flight.preset) !== "") out.preset = text(flight.preset);
    if (text(flight.seed) !== "") out.seed = text(flight.seed);
    if (text(flight.controller) !== "") out.controller = text(flight.controller);
    // Every other preset brings its own wind (the panel disables the field; the server refuses the pair).
    if (text(flight.preset) === "ideal" && text(flight.disturbance) !== "") out.disturbance = text(flight.disturbance);
  }
  if (SCALING_FORMATS.includes(format)) {
    if (text(fields.scale) !== "" && Number(text(fields.scale)) !== 1) out.scale = text(fields.scale);
    if (text(fields.offset) !== "") out.offset = text(fields.offset);
  }
  return out;
}
