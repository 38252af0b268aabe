// Unit tests of the editor's point geometry (frontend/js/geometry.js), against brute force and closed forms.
import assert from "node:assert/strict";
import { test } from "node:test";

import {
  centroid, fitToCount, largestRemainder, resamplePolylines, rotateInView, roundPoints, scaleAbout,
} from "../../frontend/js/geometry.js";

function rng(seed) {
  let s = seed >>> 0;
  return () => ((s = (Math.imul(s, 1664525) + 1013904223) >>> 0) / 4294967296);
}

const dist = (a, b) => Math.hypot(...a.map((v, i) => v - b[i]));

test("largestRemainder sums to the total and stays within one of the exact share", () => {
  const r = rng(1);
  for (let trial = 0; trial < 200; trial++) {
    const weights = Array.from({ length: 1 + Math.floor(r() * 8) }, () => r() * 10);
    const total = Math.floor(r() * 500);
    const out = largestRemainder(weights, total);
    const sum = weights.reduce((a, b) => a + b, 0);
    assert.equal(out.reduce((a, b) => a + b, 0), total);
    out.forEach((k, i) => {
      const exact = (weights[i] * total) / sum;
      assert.ok(Number.isInteger(k) && k >= Math.floor(exact) && k <= Math.ceil(exact), `${k} vs ${exact}`);
    });
  }
  assert.deepEqual(largestRemainder([0, 0], 5), [5, 0]);
});

test("resamplePolylines spaces points evenly along a straight line, ends included", () => {
  const out = resamplePolylines([[[0, 0, 0], [10, 0, 0]]], 11);
  assert.equal(out.length, 11);
  out.forEach((p, i) => assert.ok(Math.abs(p[0] - i) < 1e-12 && p[1] === 0 && p[2] === 0));
});

test("resamplePolylines shares points by length and treats a closed loop without a doubled seam", () => {
  const square = [[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0], [0, 0, 0]];
  const loop = resamplePolylines([square], 16, 1e-6);
  assert.equal(loop.length, 16);
  for (let i = 0; i < 16; i++) assert.ok(Math.abs(dist(loop[i], loop[(i + 1) % 16]) - 1) < 1e-9);
  const two = resamplePolylines([[[0, 0, 0], [30, 0, 0]], [[0, 5, 0], [10, 5, 0]]], 8);
  assert.equal(two.filter((p) => p[1] === 0).length, 6);
  assert.deepEqual(resamplePolylines([], 5), []);
});

test("fitToCount returns exactly n points and keeps colours from the source", () => {
  const r = rng(2);
  const pts = Array.from({ length: 37 }, (_, i) => [i * 0.5, Math.sin(i), 0]);
  const cols = pts.map((_, i) => (i < 20 ? "#ff0000" : "#00ff00"));
  for (const n of [0, 1, 10, 37, 80, 200]) {
    const out = fitToCount(pts, cols, n);
    assert.equal(out.points.length, n);
    assert.equal(out.colors.length, n);
    out.colors.forEach((c) => assert.ok(c === "#ff0000" || c === "#00ff00"));
  }
  const same = fitToCount(pts, cols, 37);
  assert.deepEqual(same.points, pts);
  assert.notEqual(same.points[0], pts[0]); // a copy, not the caller's arrays
  void r;
});

test("scaleAbout keeps the centroid and scales every distance to it", () => {
  const r = rng(3);
  const pts = Array.from({ length: 25 }, () => [r() * 10, r() * 10, r() * 10]);
  const idx = [...pts.keys()];
  const c0 = centroid(pts, idx);
  const before = pts.map((p) => dist(p, c0));
  scaleAbout(pts, idx, 2.5);
  const c1 = centroid(pts, idx);
  c1.forEach((v, a) => assert.ok(Math.abs(v - c0[a]) < 1e-9));
  pts.forEach((p, i) => assert.ok(Math.abs(dist(p, c1) - 2.5 * before[i]) < 1e-9));
});

test("rotateInView is a rigid rotation in the view plane, counter-clockwise as seen", () => {
  const r = rng(4);
  const pts = Array.from({ length: 20 }, () => [r() * 10, r() * 10, r() * 10]);
  const copy = pts.map((p) => p.slice());
  const idx = [...pts.keys()];
  rotateInView(pts, idx, 90, "top");
  for (let i = 0; i < pts.length; i++) {
    assert.equal(pts[i][2], copy[i][2]); // depth axis untouched
    for (let j = 0; j < i; j++) assert.ok(Math.abs(dist(pts[i], pts[j]) - dist(copy[i], copy[j])) < 1e-9);
  }
  const one = [[1, 0, 0], [-1, 0, 0]];
  rotateInView(one, [0, 1], 90, "top"); // about the origin: +x goes to +y
  assert.ok(Math.abs(one[0][0]) < 1e-12 && Math.abs(one[0][1] - 1) < 1e-12);
  const front = [[1, 0, 0], [-1, 0, 0]];
  rotateInView(front, [0, 1], 90, "front"); // front view: x right, z up
  assert.ok(Math.abs(front[0][2] - 1) < 1e-12 && front[0][1] === 0);
});

test("roundPoints rounds to millimetres and never yields -0", () => {
  assert.deepEqual(roundPoints([[1.23456, -0.0001, 2.0005]]), [[1.235, 0, 2.001]]);
  assert.ok(!Object.is(roundPoints([[-0.0001, 0, 0]])[0][0], -0));
});
