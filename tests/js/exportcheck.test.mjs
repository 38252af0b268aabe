// What the editor checks before an export (frontend/js/exportcheck.js): the QGroundControl formats need the
// show's origin (caught in the editor, no 422 from the server), and the typed origin keeps the show file's bounds.
import assert from "node:assert/strict";
import { test } from "node:test";

import {
  exportProblem, exportQuery, FLOWN_FORMATS, GEO_FORMATS, MAX_ORIGIN_ALT_M, MIN_ORIGIN_ALT_M, parseOrigin, SAMPLED_FORMATS,
  SCALING_FORMATS,
} from "../../frontend/js/exportcheck.js";

test("the QGC formats without an origin are refused here, pointing at the origin field", () => {
  for (const f of GEO_FORMATS) {
    assert.match(exportProblem(f, null), /Origin/);
    assert.equal(exportProblem(f, { origin_lat_deg: 47, origin_lon_deg: 8, origin_alt_m: 400, heading_deg: 0 }), "");
  }
  for (const f of ["show", "skyc", "skybrush-csv", "crazyswarm", "waypoints-csv", "viser-html"]) {
    assert.equal(exportProblem(f, null), "", f);
  }
});

test("origins: two or three numbers within the show file's ranges", () => {
  assert.deepEqual(parseOrigin("47.3977, 8.5456, 410").value, [47.3977, 8.5456, 410]);
  assert.deepEqual(parseOrigin("47.3977 8.5456").value, [47.3977, 8.5456, 0]);
  assert.deepEqual(parseOrigin(`0,0,${MAX_ORIGIN_ALT_M}`).value, [0, 0, MAX_ORIGIN_ALT_M]);
  assert.deepEqual(parseOrigin(`0,0,${MIN_ORIGIN_ALT_M}`).value, [0, 0, MIN_ORIGIN_ALT_M]);
  for (const bad of ["", "47", "1,2,3,4", "a,b", "91,0", "0,181", `0,0,${MAX_ORIGIN_ALT_M + 1}`, `0,0,${MIN_ORIGIN_ALT_M - 1}`]) {
    const out = parseOrigin(bad);
    assert.equal(out.value, null, bad);
    assert.match(out.error, /^Origin/, bad);
  }
  assert.match(parseOrigin("0,0,50000").error, /altitude.*10000/);
});

const ALL = ["show", "skybrush-csv", "skyc", "crazyswarm", "qgc-plan", "qgc-wpl", "waypoints-csv", "viser-html"];

test("scale and offset go only to the formats that apply them (the server refuses them elsewhere)", () => {
  const fields = { fps: "", source: "planned", scale: "0.02", offset: "1, 2, 0" };
  for (const f of ALL) {
    const q = exportQuery(f, fields);
    if (SCALING_FORMATS.includes(f)) assert.deepEqual(q, { scale: "0.02", offset: "1,2,0" }, f);
    else assert.deepEqual(q, {}, f);
  }
  assert.deepEqual(exportQuery("crazyswarm", { scale: "1", offset: "" }), {}); // the identity is the default
});

test("the flown trajectories carry the simulation panel's preset and seed", () => {
  const fields = { fps: "25", source: "simulated", scale: "", offset: "" };
  const flight = { preset: "gusty-rtk", seed: "17" };
  for (const f of FLOWN_FORMATS) {
    assert.deepEqual(exportQuery(f, fields, flight), { fps: "25", source: "simulated", preset: "gusty-rtk", seed: "17" }, f);
  }
  // A format of the exact plan cannot hold them: caught in the editor (no request the server would refuse).
  assert.deepEqual(exportQuery("skyc", fields, flight), {});
  for (const f of ALL) {
    const problem = exportProblem(f, { origin_lat_deg: 47, origin_lon_deg: 8, origin_alt_m: 400, heading_deg: 0 }, "simulated");
    if (FLOWN_FORMATS.includes(f)) assert.equal(problem, "", f);
    else assert.match(problem, /exact plan.*planned/, f);
  }
  // The planned trajectories fly nothing: no preset, no seed (the server refuses them there).
  assert.deepEqual(exportQuery("waypoints-csv", { ...fields, source: "planned" }, flight), { fps: "25" });
  assert.deepEqual(exportQuery("waypoints-csv", fields, { preset: "calm-rtk", seed: " " }),
    { fps: "25", source: "simulated", preset: "calm-rtk" });
});

test("the rate goes only to the formats that sample (the others hold exact trajectories and refuse it)", () => {
  for (const f of ALL) {
    const q = exportQuery(f, { fps: "25", source: "planned" });
    assert.deepEqual(q, SAMPLED_FORMATS.includes(f) ? { fps: "25" } : {}, f);
  }
});

test("the editor never sends an origin: the place on Earth is the show's settings.geo (the server refuses an origin given to a format that does not use it)", () => {
  for (const format of ["show", "skybrush-csv", "skyc", "crazyswarm", "qgc-plan", "qgc-wpl", "waypoints-csv", "viser-html"]) {
    const q = exportQuery(format, { fps: "25", source: "simulated", scale: "0.5", offset: "1,0,0" }, { preset: "ideal", seed: "3" });
    assert.ok(!("origin" in q), `${format}: ${JSON.stringify(q)}`);
  }
});

test("the flown trajectories carry the panel's controller, and its disturbance only with preset ideal", () => {
  const fields = { fps: "", source: "simulated", scale: "", offset: "" };
  assert.deepEqual(exportQuery("waypoints-csv", fields, { preset: "calm-rtk", seed: "0", controller: "baseline", disturbance: "wind" }),
    { source: "simulated", preset: "calm-rtk", seed: "0", controller: "baseline" });
  assert.deepEqual(exportQuery("skybrush-csv", fields, { preset: "ideal", seed: "2", controller: "ismc", disturbance: "wind" }),
    { source: "simulated", preset: "ideal", seed: "2", controller: "ismc", disturbance: "wind" });
  // Planned trajectories fly nothing: no controller, no disturbance.
  assert.deepEqual(exportQuery("waypoints-csv", { source: "planned" }, { preset: "ideal", controller: "baseline", disturbance: "wind" }), {});
});
