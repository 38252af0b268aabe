// @ts-check
// A single flight in plain terms (no DOM, run under node --test): the request the simulate panel
// sends (error preset and seed; a Monte-Carlo of K runs starts at that seed, so its run 0 is the
// single flight of the same seed), the seed's bounds, and the rows of the flight summary.

import { fmt } from "./summary.js";

/** Error-model presets (sim.flight.PRESETS, the API's PresetName). */
export const PRESETS = ["ideal", "calm-rtk", "gusty-rtk", "gps-only"];
/** What a flight flies unless the designer picks another (sim.flight.DEFAULT_FLIGHT_PRESET). */
export const DEFAULT_PRESET = "calm-rtk";
/** Largest seed the API takes (app.api.models.MAX_SEED). */
export const MAX_SEED = 2147483647;

/** What each divergence reason means physically (sim.flight.engines._state). */
export const REASONS = {
  overpowered: "overpowered: held at its tilt/thrust limit and blown off (wind beyond its authority)",
  runaway: "runaway: unstable control or a tumble",
  "non-finite": "non-finite: the state broke down",
  ground: "ground: crashed: sank 0.5 m below the show's ground",
};

/**
 * Why a typed seed cannot be used ("" when it can).
 * @param {string} text the seed field's text
 * @returns {string}
 */
export function seedProblem(text) {
  const t = String(text).trim();
  if (!/^\d+$/.test(t) || Number(t) > MAX_SEED) {
    return `Seed: a whole number from 0 to ${MAX_SEED} (the same seed flies the same flight)`;
  }
  return "";
}

/**
 * A fresh seed, uniform over 0..MAX_SEED.
 * @param {() => number} [random] uniform in [0, 1)
 * @returns {number}
 */
export function randomSeed(random = Math.random) {
  return Math.min(MAX_SEED, Math.floor(random() * (MAX_SEED + 1)));
}

/**
 * The job to start: one flight (POST /simulate) or a Monte-Carlo (POST /montecarlo) whose first run is
 * that flight (seed0 = seed). A fleet-wide disturbance goes with the ideal vehicle only: the other
 * presets bring their own wind (the API refuses both together).
 * @param {{runs: number, preset: string, seed: number, controller: string, disturbance: string}} o
 * @returns {{kind: "simulate"|"montecarlo", options: Record<string, string|number>}}
 */
export function flightRequest({ runs, preset, seed, controller, disturbance }) {
  if (runs > 1) return { kind: "montecarlo", options: { runs, preset, controller, seed0: seed } };
  return {
    kind: "simulate",
    options: { preset, seed, controller, disturbance: preset === "ideal" ? disturbance : "none" },
  };
}

/**
 * "2 overpowered (drones 3, 5), 1 ground (drone 7)": the drones that diverged, grouped by reason.
 * @param {{drone: number, time_s: number, reason: string}[]} diverged
 * @returns {string}
 */
export function divergedText(diverged) {
  /** @type {Map<string, number[]>} */
  const by = new Map();
  for (const d of diverged || []) {
    if (!by.has(d.reason)) by.set(d.reason, []);
    by.get(d.reason).push(d.drone);
  }
  return [...by].map(([why, drones]) => {
    drones.sort((a, b) => a - b);
    const shown = drones.slice(0, 8).join(", ") + (drones.length > 8 ? ", …" : "");
    return `${drones.length} ${why} (drone${drones.length > 1 ? "s" : ""} ${shown})`;
  }).join(", ");
}

/**
 * The flight summary's rows: what was flown (preset and seed), how far the drones strayed from the plan,
 * the flown minimum separation against the limit, the closest pair and when, and the drones that diverged
 * and why. Each row is [label, value, breaks a limit]; falsy rows are left out by the table.
 * @param {any} f the job's `result.flight` (FlightResult.summary() with `preset` and `seed`)
 * @param {boolean} [cached] the job was answered from the cache
 * @returns {Array<[string, string, boolean?] | false>}
 */
export function flightRows(f, cached = false) {
  const lim = f.min_distance_limit_m;
  const flown = f.flown_min_distance_m;
  const worst = Array.isArray(f.worst_drones) && f.worst_drones.length ? f.worst_drones[0] : null;
  const diverged = Array.isArray(f.diverged) ? f.diverged : [];
  const short = flown != null && lim != null && flown < lim - (f.flown_distance_tolerance_m || 0);
  return [
    f.preset != null && ["Error preset", `${f.preset}, seed ${f.seed ?? 0}`],
    ["Deviation from plan (RMS)", fmt(f.tracking_rms_m, 3, " m")],
    ["Deviation from plan (max)", `${fmt(f.tracking_max_m, 3, " m")}${worst ? ` (drone ${worst.drone})` : ""}`],
    // Beside the plan's own minimum at the same frames: the difference is what the errors took from the margin.
    ["Flown min separation", `${fmt(flown, 2, " m")}${[
      f.planned_min_distance_m != null && `plan ${fmt(f.planned_min_distance_m, 2, " m")}`,
      lim != null && `≥ ${fmt(lim, 1)}`].filter(Boolean).join(", ").replace(/^(.+)$/, " ($1)")}`, short],
    Array.isArray(f.flown_min_distance_pair) && ["Closest flown pair",
      `drones ${f.flown_min_distance_pair.join(" & ")} at ${fmt(f.flown_min_distance_time_s, 1, " s")}`, short],
    diverged.length > 0 && ["Diverged", divergedText(diverged), true],
    ["Duration", fmt(f.duration_s, 1, " s")],
    ["Controller", [f.controller, f.engine, f.disturbance && f.disturbance !== "none" && `disturbance: ${f.disturbance}`]
      .filter(Boolean).join(", ") || "—"],
    f.wall_time_s != null && ["Computed in", `${fmt(f.wall_time_s, 1, " s")}${cached ? " (cached)" : ""}`],
  ];
}
