// The settings form's home grid follows the drone count (frontend/js/settings.js): a designer who typed a
// count by mistake (30000 for 300) and typed it again was left with a 173 x 174 grid the save refused
// ("more than 4 positions per drone"). Held to the show file's own rule (formations/_show.py: the grid
// holds every drone and has at most max(4 n, 16) positions) over every count and every way back.
import assert from "node:assert/strict";
import { test } from "node:test";

import { homeGridFor } from "../../frontend/js/settings.js";

/** The show file's rule for a home grid of `n` drones, restated from formations/_show.py. */
const valid = (g, n) => g.rows * g.cols >= n && g.rows * g.cols <= Math.max(4 * n, 16);

test("a typo and its correction give back the grid the show started with", () => {
  const start = { rows: 10, cols: 10, spacing_m: 4.5 };
  const big = homeGridFor(start, 100, 30000);
  assert.ok(valid(big, 30000));
  const back = homeGridFor(big, 30000, 100);
  assert.deepEqual(back, start);
  // 100 -> 120 -> 100: the square grid grows and shrinks back with the count.
  assert.deepEqual(homeGridFor(homeGridFor(start, 100, 120), 120, 100), start);
});

test("every count from every count: the grid is one the show file accepts", () => {
  const counts = [1, 2, 3, 5, 16, 17, 50, 99, 100, 101, 250, 999, 1000, 4097, 20000];
  for (const a of counts) {
    let g = { rows: Math.ceil(a / Math.ceil(Math.sqrt(a))), cols: Math.ceil(Math.sqrt(a)), spacing_m: 3 };
    for (const b of counts) {
      const h = homeGridFor(g, a, b);
      assert.ok(valid(h, b), `${a} -> ${b}: ${h.rows} x ${h.cols}`);
      assert.equal(h.spacing_m, 3, "the spacing is the designer's");
    }
  }
});

test("a grid the designer shaped stays while it still holds the drones", () => {
  const wide = { rows: 4, cols: 30, spacing_m: 5 };   // 120 positions, not the square one
  assert.deepEqual(homeGridFor(wide, 110, 100), wide);
  assert.deepEqual(homeGridFor(wide, 110, 120), wide);
  const grown = homeGridFor(wide, 110, 121);          // too small now: a grid that holds them
  assert.ok(valid(grown, 121));
  const shrunk = homeGridFor(wide, 110, 20);          // 120 > 4 x 20: refused by the save, so resized
  assert.ok(valid(shrunk, 20));
});
