// Unit tests of the music lane's arithmetic (frontend/js/musicmath.js) against brute force.
import assert from "node:assert/strict";
import { test } from "node:test";

import { columnPeaks, snapTime } from "../../frontend/js/musicmath.js";

function rng(seed) {
  let s = seed >>> 0;
  return () => ((s = (Math.imul(s, 1664525) + 1013904223) >>> 0) / 4294967296);
}

test("snapTime picks the nearest point within the radius, else keeps the time", () => {
  const r = rng(7);
  for (let trial = 0; trial < 500; trial++) {
    const pts = Array.from({ length: Math.floor(r() * 12) }, () => r() * 60).sort((a, b) => a - b);
    const t = r() * 70 - 5;
    const radius = r() * 3;
    let best = t;
    let bestD = radius;
    for (const p of pts) if (Math.abs(p - t) <= bestD) { bestD = Math.abs(p - t); best = p; }
    const got = snapTime(t, pts, radius);
    assert.equal(Math.abs(got - t), Math.abs(best - t), `${t} ${radius} ${pts}`);
    assert.ok(got === t || pts.includes(got));
  }
  assert.equal(snapTime(1.2, [0, 0.5, 1.0, 1.5], 0.3), 1.0);
  assert.equal(snapTime(1.2, [0, 0.5, 1.0, 1.5], 0.1), 1.2);
});

test("columnPeaks is the min and max of the buckets each column covers", () => {
  const r = rng(3);
  const perS = 50;
  const n = 1234;
  const peaks = [];
  for (let i = 0; i < n; i++) {
    const a = Math.round(r() * 254 - 127);
    const b = Math.round(r() * 254 - 127);
    peaks.push(Math.min(a, b), Math.max(a, b));
  }
  const width = 97;
  const t1 = n / perS;
  const cols = columnPeaks(peaks, perS, 0, t1, width);
  for (let x = 0; x < width; x++) {
    const a = Math.floor(((t1 * x) / width) * perS);
    const b = Math.max(a + 1, Math.floor(((t1 * (x + 1)) / width) * perS));
    let lo = 0;
    let hi = 0;
    for (let i = a; i < Math.min(b, n); i++) { lo = Math.min(lo, peaks[2 * i]); hi = Math.max(hi, peaks[2 * i + 1]); }
    assert.ok(Math.abs(cols[2 * x] - lo / 127) < 1e-6 && Math.abs(cols[2 * x + 1] - hi / 127) < 1e-6, `column ${x}`);
  }
  // Beyond the track: silence.
  const after = columnPeaks(peaks, perS, t1 + 1, t1 + 2, 4);
  assert.deepEqual(Array.from(after), [0, 0, 0, 0, 0, 0, 0, 0]);
});
