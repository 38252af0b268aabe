// Unit tests of the editor's plan-aware light preview (frontend/js/lighteval.js: evaluatePlanned,
// formationWindows, planUsable) against brute force: drone by drone, where the plan sends it. (Its
// parity with the server's evaluator on a planned show is tests/test_light_preview_parity.py's.)
import assert from "node:assert/strict";
import { test } from "node:test";

import { evaluateColors, evaluatePlanned, formationWindows, hash01, planUsable } from "../../frontend/js/lighteval.js";

function rng(seed) {
  let s = seed >>> 0;
  return () => ((s = (Math.imul(s, 1664525) + 1013904223) >>> 0) / 4294967296);
}

function shuffle(n, r) {
  const a = Array.from({ length: n }, (_, i) => i);
  for (let i = n - 1; i > 0; i--) {
    const j = Math.floor(r() * (i + 1));
    [a[i], a[j]] = [a[j], a[i]];
  }
  return a;
}

const SEGMENTS = [
  { kind: "takeoff", label: "takeoff", start_s: 0, duration_s: 5 },
  { kind: "transition", label: "A", start_s: 5, duration_s: 4 },
  { kind: "hold", label: "A", start_s: 9, duration_s: 6 },
  { kind: "transition", label: "B", start_s: 15, duration_s: 5 },
  { kind: "hold", label: "B", start_s: 20, duration_s: 3 },
  { kind: "transition", label: "A", start_s: 23, duration_s: 2 },
  { kind: "hold", label: "A", start_s: 25, duration_s: 1 },
  { kind: "landing", label: "landing", start_s: 26, duration_s: 6 },
];

test("formationWindows run from the transition into a formation to the end of its hold", () => {
  const w = formationWindows({ segments: SEGMENTS });
  assert.deepEqual(w.get("A"), [[5, 15], [23, 26]]);
  assert.deepEqual(w.get("B"), [[15, 23]]);
  assert.equal(w.get("takeoff"), undefined);
});

test("planUsable needs one assignment of the drone count per formation", () => {
  const plan = { drones: 3, segments: [], assignment: [[2, 0, 1], [0, 1, 2]] };
  assert.ok(planUsable(plan, 3, 2));
  assert.ok(!planUsable(plan, 4, 2));
  assert.ok(!planUsable(plan, 3, 3));
  assert.ok(!planUsable({ ...plan, assignment: [[2, 0], [0, 1, 2]] }, 3, 2));
  assert.ok(!planUsable(null, 3, 2));
  assert.ok(!planUsable({ drones: 3, segments: [] }, 3, 2));
});

test("evaluatePlanned paints each point with the colour of the drone the plan sends there", () => {
  const r = rng(11);
  const n = 12;
  for (let trial = 0; trial < 40; trial++) {
    const assignment = [shuffle(n, r), shuffle(n, r)];
    const plan = { drones: n, segments: SEGMENTS, assignment };
    const k = trial % 2;
    const name = ["A", "B"][k];
    const points = Array.from({ length: n }, () => [r() * 20 - 10, r() * 4, 20 + r() * 10]);
    const base = Array.from({ length: n }, () => [r(), r(), r()]);
    const drones = [0, 3, 7];
    const group = [1, 2, 5];
    const pts = [4, 6];
    const show = {
      drones: n,
      formations: [{ name: "A" }, { name: "B" }],
      lights: {
        groups: { g: group },
        effects: [
          { start_s: 0, end_s: 40, target: { kind: "drones", indices: drones }, effect: { kind: "solid", color: "#ff0000" } },
          { start_s: 0, end_s: 40, blend: "add", target: { kind: "group", group: "g" }, effect: { kind: "solid", color: "#0000ff" } },
          { start_s: 0, end_s: 40, blend: "max", target: { kind: "points", formation: "B", indices: pts },
            effect: { kind: "solid", color: "#00ff00" } },
          { start_s: 0, end_s: 40, blend: "multiply", target: { kind: "formation", formation: "A" },
            effect: { kind: "solid", color: "#808080" } },
          { start_s: 0, end_s: 40, blend: "max", effect: { kind: "sparkle", color: "#ffffff", density: 0.5, seed: 3, flash_s: 0.7 } },
        ],
      },
    };
    const t = k === 0 ? 9 + r() * 6 : 15 + r() * 8;
    const got = evaluatePlanned(show, k, points, base, t, plan);
    // Brute force, drone by drone: drone d sits on point assignment[k][d].
    const want = base.map((c) => [...c]);
    for (let d = 0; d < n; d++) {
      const p = assignment[k][d];
      const c = [...base[p]];
      if (drones.includes(d)) { c[0] = 1; c[1] = 0; c[2] = 0; }
      if (group.includes(d)) c[2] = Math.min(1, c[2] + 1);
      if (pts.includes(assignment[1][d])) c[1] = 1;
      if (name === "A") for (let ch = 0; ch < 3; ch++) c[ch] *= 128 / 255;
      const x = (t - 0) / 0.7 + hash01(3, d, -1);
      const slot = Math.floor(x);
      if (hash01(3, d, slot) < 0.5) {
        const a = 1 - Math.abs(2 * (x - slot) - 1);
        for (let ch = 0; ch < 3; ch++) c[ch] = c[ch] + a * (Math.max(c[ch], 1) - c[ch]);
      }
      want[p] = c;
    }
    for (let p = 0; p < n; p++) {
      for (let ch = 0; ch < 3; ch++) assert.ok(Math.abs(got[p][ch] - want[p][ch]) < 1e-12, `trial ${trial} point ${p}`);
    }
  }
});

test("with the identity assignment and its formation on screen it is the drone-on-point preview", () => {
  const r = rng(5);
  const n = 8;
  const points = Array.from({ length: n }, () => [r() * 10, 0, 20 + r() * 5]);
  const base = Array.from({ length: n }, () => [r(), r(), r()]);
  const show = { drones: n, formations: [{ name: "A" }, { name: "B" }], lights: { effects: [
    { start_s: 0, end_s: 40, effect: { kind: "sweep", colors: ["#ff0000", "#00ff00"], axis: [1, 0, 0], length_m: 6, speed_mps: 3 } },
    { start_s: 0, end_s: 40, blend: "add", effect: { kind: "chase", color: "#ffffff", period_s: 2, width: 0.3 } },
  ] } };
  const plan = { drones: n, segments: SEGMENTS, assignment: [points.map((_, i) => i), points.map((_, i) => i)] };
  for (const t of [9.5, 11, 13.7]) {
    assert.deepEqual(evaluatePlanned(show, 0, points, base, t, plan), evaluateColors(show, "A", points, base, t));
  }
});
