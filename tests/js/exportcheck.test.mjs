// What the editor checks before an export (frontend/js/exportcheck.js): the QGroundControl formats need the
// show's origin (caught in the editor, no 422 from the server), and the typed origin keeps the show file's bounds.
import assert from "node:assert/strict";
import { test } from "node:test";

import { exportProblem, GEO_FORMATS, MAX_ORIGIN_ALT_M, MIN_ORIGIN_ALT_M, parseOrigin } from "../../frontend/js/exportcheck.js";

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
