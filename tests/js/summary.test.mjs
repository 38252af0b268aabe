// The check report's planner line in plain words (frontend/js/summary.js): a designer read "Planner: none." as
// "no planner ran". Every resolution the planner reports (sim.plan: TransitionInfo.resolution) has a sentence.
import assert from "node:assert/strict";
import { test } from "node:test";

import { limitRow, plannerText } from "../../frontend/js/summary.js";

test("every resolution the planner reports reads as a sentence, not its code", () => {
  for (const code of ["none", "delays", "layers", "unresolved"]) {
    const text = plannerText(code);
    assert.ok(text.length > 20, text);
    assert.ok(!new RegExp(`\\b${code}\\b`).test(text), `${code}: ${text}`);
  }
  assert.match(plannerText("none"), /straight line/);
  assert.match(plannerText("unresolved"), /not/);
});

test("an unknown resolution is shown as it is, and none at all says nothing", () => {
  assert.equal(plannerText("swirl"), "Planner: swirl.");
  assert.equal(plannerText(""), "");
});

test("a check row with no value (one drone: no pair, min_distance_m null) says so and breaks no limit", () => {
  const none = "none (one drone, no pair)";
  assert.deepEqual(limitRow("Minimum distance", null, 3, "m", "min", none),
    ["Minimum distance", "none (one drone, no pair) (≥ 3.0)", false]);
  // What the server said before (-1) was drawn as a distance below the limit.
  assert.deepEqual(limitRow("Minimum distance", 2.5, 3, "m", "min", none), ["Minimum distance", "2.50 m (≥ 3.0)", true]);
  assert.deepEqual(limitRow("Minimum distance", 3.2, 3, "m", "min", none), ["Minimum distance", "3.20 m (≥ 3.0)", false]);
  assert.deepEqual(limitRow("Peak horizontal speed", 12, 10, "m/s", "max"), ["Peak horizontal speed", "12.00 m/s (≤ 10.0)", true]);
  assert.deepEqual(limitRow("Peak horizontal speed", 4, undefined, "m/s", "max"), ["Peak horizontal speed", "4.00 m/s", false]);
});

test("a check group with no pair (min_distance_m null) orders last and says none, not 0 or -1", async () => {
  const { closestText, distanceForOrder } = await import("../../frontend/js/summary.js");
  // `null >= 0` is true in JavaScript: the editor's old test ordered "no pair" as distance 0, worst of all.
  assert.equal(distanceForOrder(null), Infinity);
  assert.equal(distanceForOrder(undefined), Infinity);
  assert.equal(distanceForOrder(-1), Infinity);
  assert.equal(distanceForOrder(2.5), 2.5);
  assert.equal(distanceForOrder(0), 0);
  const groups = [{ min_distance_m: null, segment: 0 }, { min_distance_m: 2.5, segment: 1 }, { min_distance_m: 3.1, segment: 2 }];
  assert.deepEqual([...groups].sort((a, b) => distanceForOrder(a.min_distance_m) - distanceForOrder(b.min_distance_m))
    .map((g) => g.segment), [1, 2, 0]);
  assert.equal(closestText(3.2), ", closest 3.20 m");
  assert.match(closestText(null), /none/);
  assert.doesNotMatch(closestText(null), /-1|null|NaN|Infinity|—/);
});
