// Unit tests of the editor's motion preview (frontend/js/motion.js) against closed forms; the
// Python side (tests/test_plan_motion.py) holds it to formations/_motion.py on random motions.
import assert from "node:assert/strict";
import { test } from "node:test";

import { channelsAt, movedPoints, pivotOf } from "../../frontend/js/motion.js";

const close = (a, b, tol = 1e-9) => a.forEach((v, i) => assert.ok(Math.abs(v - b[i]) <= tol, `${a} vs ${b}`));
const GRID = [[-5, 0, 35], [0, 0, 35], [5, 0, 35], [-5, 0, 45], [5, 0, 45]];

test("a quarter turn about z ends at (-y, x, z) about the centroid and passes 45 deg halfway (smooth)", () => {
  const motion = { keys: [{ t_s: 0 }, { t_s: 10, rotate_deg: [0, 0, 90] }] };
  const c = pivotOf(motion, GRID);
  close(c, [0, 0, 39]);
  movedPoints(motion, GRID, 10).forEach((p, i) => close(p, [c[0] - (GRID[i][1] - c[1]), c[1] + GRID[i][0] - c[0], GRID[i][2]]));
  close([channelsAt(motion, 5)[5]], [Math.PI / 4]);
  // Before the first key and after the last the formation rests.
  close(channelsAt(motion, -3), [0, 0, 0, 0, 0, 0, 1]);
  close(channelsAt(motion, 99).slice(5, 6), [Math.PI / 2]);
});

test("Euler angles compose as R_z R_y R_x (fixed axes x, then y, then z)", () => {
  const motion = { pivot_m: [0, 0, 0], keys: [{ t_s: 0, rotate_deg: [90, 0, 90] }, { t_s: 1, rotate_deg: [90, 0, 90] }] };
  const [a, b] = movedPoints(motion, [[1, 0, 0], [0, 1, 0]], 0.5);
  close(a, [0, 1, 0]);
  close(b, [0, 0, 1]);
});

test("evenly timed linear keys move at a constant rate; scale and translation apply about the pivot", () => {
  const motion = { pivot_m: [0, 0, 40], keys: [
    { t_s: 0 }, { t_s: 2, translate_m: [2, 0, 0], easing: "linear" }, { t_s: 4, translate_m: [4, 0, 0], easing: "linear" },
    { t_s: 6, translate_m: [6, 0, 0], scale: 2 }] };
  close([channelsAt(motion, 2.5)[0], channelsAt(motion, 3)[0], channelsAt(motion, 3.5)[0]], [2.5, 3, 3.5]);
  close(movedPoints(motion, [[1, 0, 41]], 6)[0], [8, 0, 42]);
});
