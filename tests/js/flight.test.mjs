// The simulate panel's single flight (frontend/js/flight.js): the request carries the error preset and the
// seed (a Monte-Carlo starts at that seed, so its run 0 is the same flight), seeds are checked against the
// API's bound, and the summary rows say what matters with errors on.
import assert from "node:assert/strict";
import { test } from "node:test";

import { divergedText, flightRequest, flightRows, MAX_SEED, PRESETS, randomSeed, seedProblem } from "../../frontend/js/flight.js";

test("one flight carries preset and seed; a disturbance only with the ideal vehicle", () => {
  const base = { runs: 1, preset: "gusty-rtk", seed: 42, controller: "ismc", disturbance: "wind" };
  assert.deepEqual(flightRequest(base), { kind: "simulate",
    options: { preset: "gusty-rtk", seed: 42, controller: "ismc", disturbance: "none" } });
  assert.deepEqual(flightRequest({ ...base, preset: "ideal" }).options.disturbance, "wind");
});

test("a Monte-Carlo starts at the seed (its run 0 is the single flight of that seed)", () => {
  const req = flightRequest({ runs: 20, preset: "calm-rtk", seed: 7, controller: "baseline", disturbance: "paper" });
  assert.deepEqual(req, { kind: "montecarlo", options: { runs: 20, preset: "calm-rtk", controller: "baseline", seed0: 7 } });
});

test("seeds: whole numbers from 0 to the API's bound", () => {
  for (const ok of ["0", "7", " 12 ", String(MAX_SEED)]) assert.equal(seedProblem(ok), "", ok);
  for (const bad of ["", "-1", "1.5", "1e3", "abc", String(MAX_SEED + 1)]) assert.match(seedProblem(bad), /Seed/, bad);
  assert.equal(MAX_SEED, 2 ** 31 - 1);
  assert.equal(randomSeed(() => 0), 0);
  assert.equal(randomSeed(() => 0.999999999999), MAX_SEED);
  for (let i = 0; i < 100; i++) assert.equal(seedProblem(String(randomSeed())), "");
  assert.deepEqual(PRESETS, ["ideal", "calm-rtk", "gusty-rtk", "gps-only"]);
});

test("diverged drones are grouped by reason with their numbers", () => {
  const d = [{ drone: 5, time_s: 1, reason: "overpowered" }, { drone: 7, time_s: 2, reason: "ground" },
    { drone: 3, time_s: 3, reason: "overpowered" }];
  assert.equal(divergedText(d), "2 overpowered (drones 3, 5), 1 ground (drone 7)");
  const many = Array.from({ length: 10 }, (_, i) => ({ drone: i, time_s: 0, reason: "runaway" }));
  assert.equal(divergedText(many), "10 runaway (drones 0, 1, 2, 3, 4, 5, 6, 7, …)");
  assert.equal(divergedText([]), "");
});

test("summary rows: preset and seed, deviations, separation against the limit, pair, divergences", () => {
  const f = { preset: "calm-rtk", seed: 5, tracking_rms_m: 0.0312, tracking_max_m: 0.0889,
    worst_drones: [{ drone: 11, rms_m: 0.04, max_m: 0.0889 }], flown_min_distance_m: 2.95, min_distance_limit_m: 3, planned_min_distance_m: 3.243,
    flown_distance_tolerance_m: 0.01, flown_min_distance_pair: [7, 11], flown_min_distance_time_s: 21.9,
    diverged: [{ drone: 2, time_s: 40, reason: "overpowered" }], duration_s: 84, controller: "ismc",
    engine: "numba", disturbance: "none", wall_time_s: 1.25 };
  const rows = flightRows(f, true).filter(Boolean);
  assert.deepEqual(rows, [
    ["Error preset", "calm-rtk, seed 5"],
    ["Deviation from plan (RMS)", "0.031 m"],
    ["Deviation from plan (max)", "0.089 m (drone 11)"],
    ["Flown min separation", "2.95 m (plan 3.24 m, ≥ 3.0)", true],
    ["Closest flown pair", "drones 7 & 11 at 21.9 s", true],
    ["Diverged", "1 overpowered (drone 2)", true],
    ["Duration", "84.0 s"],
    ["Controller", "ismc, numba"],
    ["Computed in", "1.3 s (cached)"],
  ]);
  // Within the tolerance is kept; an old result without preset has no preset row.
  const kept = flightRows({ ...f, preset: undefined, flown_min_distance_m: 2.995, diverged: [],
    planned_min_distance_m: undefined }).filter(Boolean);
  assert.deepEqual(kept.find((r) => r[0] === "Flown min separation"), ["Flown min separation", "3.00 m (≥ 3.0)", false]);
  assert.equal(flightRows({ flown_min_distance_m: 4 }).filter(Boolean).find((r) => r[0] === "Flown min separation")[1],
    "4.00 m");
  assert.equal(kept[0][0], "Deviation from plan (RMS)");
  assert.equal(kept.find((r) => r[0] === "Flown min separation")[2], false);
  assert.ok(!kept.some((r) => r[0] === "Diverged"));
});
