// Unit tests of the launch-layout panel's geometry (frontend/js/launch.js): box positions as the show file
// lays them out (formations/_launch.py), and the wave preview against a brute-force colouring.
import assert from "node:assert/strict";
import { test } from "node:test";

import { boxPositions, homePositions, previewWaves } from "../../frontend/js/launch.js";

function rng(seed) {
  let s = seed >>> 0;
  return () => ((s = (Math.imul(s, 1664525) + 1013904223) >>> 0) / 4294967296);
}

test("boxes: each box's pattern around its centre, box by box", () => {
  const { points, box } = boxPositions({ per_box: 8, cols: 4, spacing_m: 0.8, grid: { rows: 2, cols: 3, spacing_m: 6 } });
  assert.equal(points.length, 48);
  assert.deepEqual(box.slice(0, 9), [0, 0, 0, 0, 0, 0, 0, 0, 1]);
  // first box centred at (-6, -3): columns at -1.2, -0.4, 0.4, 1.2 and rows at -0.4, 0.4
  assert.ok(Math.abs(points[0][0] - (-7.2)) < 1e-12 && Math.abs(points[0][1] - (-3.4)) < 1e-12);
  assert.ok(Math.abs(points[7][0] - (-4.8)) < 1e-12 && Math.abs(points[7][1] - (-2.6)) < 1e-12);
  const grid = homePositions({ home: { grid: { rows: 2, cols: 2, spacing_m: 3 } } });
  assert.deepEqual(grid.points, [[-1.5, -1.5, 0], [1.5, -1.5, 0], [-1.5, 1.5, 0], [1.5, 1.5, 0]]);
});

function chromatic(n, edges) {
  for (let k = 1; k <= n; k++) {
    const c = new Array(n).fill(0);
    const ok = (i) => {
      if (i === n) return true;
      for (let v = 0; v < k; v++) {
        c[i] = v;
        if (edges.every(([a, b]) => (a > i || b > i) || c[a] !== c[b]) && ok(i + 1)) return true;
      }
      return false;
    };
    if (ok(0)) return k;
  }
  return n;
}

test("wave preview: a proper colouring, minimal on box layouts and small random ones", () => {
  const boxes = boxPositions({ per_box: 8, cols: 4, spacing_m: 0.8, grid: { rows: 1, cols: 2, spacing_m: 6 } });
  assert.equal(previewWaves(boxes.points, 3).waves, 8);
  const r = rng(5);
  for (let trial = 0; trial < 20; trial++) {
    const pts = Array.from({ length: 7 }, () => [r() * 8, r() * 8, 0]);
    const { waves, wave } = previewWaves(pts, 3);
    const edges = [];
    for (let i = 0; i < pts.length; i++) {
      for (let j = i + 1; j < pts.length; j++) {
        if (Math.hypot(pts[i][0] - pts[j][0], pts[i][1] - pts[j][1]) < 3 * (1 - 1e-9)) edges.push([i, j]);
      }
    }
    for (const [a, b] of edges) assert.notEqual(wave[a], wave[b]);
    assert.ok(waves >= chromatic(pts.length, edges) && waves <= chromatic(pts.length, edges) + 1);
  }
  assert.equal(previewWaves([[0, 0, 0], [3, 0, 0]], 3).waves, 1); // exactly the minimum apart: together
});
