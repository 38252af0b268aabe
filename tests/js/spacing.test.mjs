// Unit tests of the editor's spacing checks (frontend/js/spacing.js) against an O(n²) brute force.
import assert from "node:assert/strict";
import { test } from "node:test";

import { closePairs, nearestPairDistance, repairSpacing } from "../../frontend/js/spacing.js";

function rng(seed) {
  let s = seed >>> 0;
  return () => ((s = (Math.imul(s, 1664525) + 1013904223) >>> 0) / 4294967296);
}

const dist = (a, b) => Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);

function brutePairs(points, limit) {
  const out = [];
  for (let i = 0; i < points.length; i++) {
    for (let j = i + 1; j < points.length; j++) {
      const d = dist(points[i], points[j]);
      if (d < limit - 1e-9) out.push([i, j]);
    }
  }
  return out;
}

function bruteMin(points) {
  let best = Infinity;
  for (let i = 0; i < points.length; i++) for (let j = i + 1; j < points.length; j++) best = Math.min(best, dist(points[i], points[j]));
  return best;
}

function cloud(r, n, size) {
  return Array.from({ length: n }, () => [(r() - 0.5) * size, (r() - 0.5) * size, (r() - 0.5) * size]);
}

test("closePairs finds exactly the brute-force pairs, negative coordinates included", () => {
  const r = rng(7);
  for (let trial = 0; trial < 30; trial++) {
    const pts = cloud(r, 5 + Math.floor(r() * 120), 20);
    const limit = 0.5 + r() * 3;
    const got = closePairs(pts, limit).pairs.map(([i, j]) => `${i},${j}`).sort();
    const want = brutePairs(pts, limit).map(([i, j]) => `${i},${j}`).sort();
    assert.deepEqual(got, want);
  }
});

test("closePairs with a subset reports each pair touching the subset once", () => {
  const r = rng(8);
  const pts = cloud(r, 80, 10);
  const only = [3, 17, 40, 41];
  const got = closePairs(pts, 2.0, only).pairs.map(([i, j]) => `${i},${j}`).sort();
  const want = brutePairs(pts, 2.0).filter(([i, j]) => only.includes(i) || only.includes(j)).map(([i, j]) => `${i},${j}`).sort();
  assert.deepEqual(got, want);
});

test("nearestPairDistance equals the brute-force minimum", () => {
  const r = rng(9);
  for (let trial = 0; trial < 30; trial++) {
    const pts = cloud(r, 2 + Math.floor(r() * 150), 1 + r() * 100);
    assert.ok(Math.abs(nearestPairDistance(pts) - bruteMin(pts)) < 1e-9);
  }
  assert.equal(nearestPairDistance([[0, 0, 0]]), Infinity);
  assert.equal(nearestPairDistance([[1, 1, 1], [1, 1, 1]]), 0);
});

test("repairSpacing leaves the input alone and reaches the minimum on a crowded cluster", () => {
  const r = rng(10);
  const pts = cloud(r, 60, 6);
  pts.push(pts[0].slice()); // a coincident pair
  const before = pts.map((p) => p.slice());
  const out = repairSpacing(pts, 1.0, { plane: [0, 2] });
  assert.deepEqual(pts, before);
  assert.ok(bruteMin(out.points) >= 1.0 - 1e-9);
  assert.ok(out.achieved === Infinity || out.achieved >= 1.0);
  assert.ok(out.moved > 0);
  // Points already far apart do not move.
  const sparse = [[0, 0, 0], [5, 0, 0], [0, 5, 0]];
  const same = repairSpacing(sparse, 1.0);
  assert.deepEqual(same.points, sparse);
  assert.equal(same.moved, 0);
});

test("roundKeepingSpacing: millimetres unless rounding brings a pair closer than the minimum distance", async () => {
  const { roundKeepingSpacing } = await import("../../frontend/js/spacing.js");
  const r = rng(7);
  // Pairs exactly 3 m apart along random directions (a source's closest pair at its fitting size): rounding each
  // coordinate to 1 mm moves the distance by up to √3 mm, below 3 m for some of them.
  let kept = 0;
  for (let trial = 0; trial < 200; trial++) {
    const a = [r() * 40, r() * 40, 10 + r() * 40];
    const t = r() * 2 * Math.PI, u = Math.acos(2 * r() - 1);
    const b = [a[0] + 3 * Math.sin(u) * Math.cos(t), a[1] + 3 * Math.sin(u) * Math.sin(t), a[2] + 3 * Math.cos(u)];
    const pts = [a, b, [a[0] + 20, a[1], a[2]]];
    const out = roundKeepingSpacing(pts, 3);
    assert.equal(brutePairs(out, 3).length, 0, `trial ${trial}: ${JSON.stringify(out)}`);
    const rounded = out.every((p) => p.every((v) => Math.abs(v * 1000 - Math.round(v * 1000)) < 1e-6));
    if (!rounded) kept++;
    // Rounded whenever the rounding keeps the distance (brute force over the rounded points).
    const mm = pts.map((p) => p.map((v) => Math.round(v * 1000) / 1000));
    assert.equal(rounded, brutePairs(mm, 3).length === 0);
  }
  assert.ok(kept > 10 && kept < 190, `${kept} of 200 kept unrounded`);
  // Points already too close (typed by hand) are rounded as usual: the repair is the designer's.
  assert.deepEqual(roundKeepingSpacing([[0, 0, 10.00049], [1, 0, 10]], 3), [[0, 0, 10], [1, 0, 10]]);
});
