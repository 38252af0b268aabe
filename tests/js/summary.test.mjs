// The check report's planner line in plain words (frontend/js/summary.js): a designer read "Planner: none." as
// "no planner ran". Every resolution the planner reports (sim.plan: TransitionInfo.resolution) has a sentence.
import assert from "node:assert/strict";
import { test } from "node:test";

import { plannerText } from "../../frontend/js/summary.js";

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
