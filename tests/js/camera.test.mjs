// Unit tests of the 3D editing math: the orbit camera's projection and unprojection
// (frontend/js/camera.js) and the rotations about an axis and toward the audience (geometry.js),
// against closed forms (pinhole projection, rotation matrices) and dense sampling.
import assert from "node:assert/strict";
import { test } from "node:test";

import { OrbitCamera, axisParameter, rayPlane } from "../../frontend/js/camera.js";
import { audiencePoint, faceAudienceDegrees, rotateAboutAxis } from "../../frontend/js/geometry.js";

function rng(seed) {
  let s = seed >>> 0;
  return () => ((s = (Math.imul(s, 1664525) + 1013904223) >>> 0) / 4294967296);
}

const close = (a, b, tol = 1e-9) => Math.abs(a - b) <= tol;
const near = (p, q, tol = 1e-9) => p.every((v, i) => close(v, q[i], tol));

function camera(yaw, pitch, target = [3, -4, 30], dist = 80) {
  const c = new OrbitCamera();
  c.yaw_rad = yaw;
  c.pitch_rad = pitch;
  c.target = target;
  c.distance_m = dist;
  c.width = 800;
  c.height = 600;
  return c;
}

test("yaw 0, pitch 0 is the audience's pinhole view along +y: x right, z up", () => {
  const c = camera(0, 0);
  const f = 300 / Math.tan(c.fov_rad / 2);
  const [sx, sy, z] = c.project(c.target);
  assert.ok(close(sx, 400) && close(sy, 300) && close(z, 80));
  // A point 6 m right, 9 m up and 20 m further away: x' = f X / Z, y' = f Y / Z.
  const p = [c.target[0] + 6, c.target[1] + 20, c.target[2] + 9];
  const [px, py, pz] = c.project(p);
  assert.ok(close(pz, 100));
  assert.ok(close(px, 400 + (f * 6) / 100, 1e-9) && close(py, 300 - (f * 9) / 100, 1e-9));
});

test("yaw 90° looks along +x (y to the left), pitch 90° looks straight down (y up the screen)", () => {
  const side = camera(Math.PI / 2, 0);
  const f = 300 / Math.tan(side.fov_rad / 2);
  const [sx, , z] = side.project([side.target[0], side.target[1] - 5, side.target[2]]);
  assert.ok(close(z, 80) && close(sx, 400 + (f * 5) / 80));
  const top = camera(0, Math.PI / 2);
  const [tx, ty, tz] = top.project([top.target[0] + 2, top.target[1] + 4, top.target[2] - 10]);
  assert.ok(close(tz, 90) && close(tx, 400 + (f * 2) / 90) && close(ty, 300 - (f * 4) / 90));
});

test("the camera frame is orthonormal and right-handed for any yaw and pitch", () => {
  const r = rng(3);
  for (let k = 0; k < 100; k++) {
    const { forward: F, right: R, up: U } = camera(r() * 7 - 3.5, r() * 3 - 1.5).frame();
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for (const v of [F, R, U]) assert.ok(close(dot(v, v), 1, 1e-12));
    assert.ok(close(dot(F, R), 0, 1e-12) && close(dot(F, U), 0, 1e-12) && close(dot(R, U), 0, 1e-12));
    // right x forward = up, and the right vector is horizontal (no roll)
    const cross = [R[1] * F[2] - R[2] * F[1], R[2] * F[0] - R[0] * F[2], R[0] * F[1] - R[1] * F[0]];
    assert.ok(near(cross, U, 1e-12) && R[2] === 0);
  }
});

test("unprojection inverts projection: the ray through a point's pixel passes through it", () => {
  const r = rng(7);
  for (let k = 0; k < 300; k++) {
    const c = camera(r() * 7 - 3.5, r() * 3 - 1.5, [r() * 50 - 25, r() * 50 - 25, r() * 60], 20 + r() * 200);
    const p = c.target.map((t) => t + (r() - 0.5) * 30);
    const [sx, sy, depth] = c.project(p);
    if (depth <= 1) continue;
    const { origin, dir } = c.ray(sx, sy);
    const t = (p[0] - origin[0]) * dir[0] + (p[1] - origin[1]) * dir[1] + (p[2] - origin[2]) * dir[2];
    const foot = origin.map((o, i) => o + t * dir[i]);
    assert.ok(near(foot, p, 1e-7), `${foot} vs ${p}`);
    // On the plane through p facing the camera, the pixel maps back to p itself.
    assert.ok(near(c.unprojectAt(sx, sy, p), p, 1e-7));
    // ... and a pixel 40 px to the right lands 40 * depth / focal metres along the right vector.
    const fr = c.frame();
    const moved = c.unprojectAt(sx + 40, sy, p);
    assert.ok(near(moved, p.map((v, i) => v + (40 * depth * fr.right[i]) / fr.focal), 1e-6));
  }
});

test("rayPlane: closed form, parallel and behind give null", () => {
  const ray = { origin: [0, 0, 0], dir: [0, 0.6, 0.8] };
  assert.deepEqual(rayPlane(ray, [5, 0, 8], [0, 0, 1]), [0, 6, 8]);
  assert.equal(rayPlane(ray, [0, 0, 5], [1, 0, 0]), null);
  assert.equal(rayPlane(ray, [0, 0, -8], [0, 0, 1]), null);
});

test("axisParameter finds the axis point nearest the ray (dense sampling agrees)", () => {
  const r = rng(11);
  const distToRay = (p, ray) => {
    const w = p.map((v, i) => v - ray.origin[i]);
    const t = w[0] * ray.dir[0] + w[1] * ray.dir[1] + w[2] * ray.dir[2];
    return Math.hypot(...w.map((v, i) => v - t * ray.dir[i]));
  };
  for (let k = 0; k < 60; k++) {
    const c = camera(r() * 6 - 3, r() * 2 - 1);
    const ray = c.ray(r() * 800, r() * 600);
    const q = [r() * 20, r() * 20, 20 + r() * 20];
    const a = [[1, 0, 0], [0, 1, 0], [0, 0, 1]][k % 3];
    const s = axisParameter(ray, q, a);
    if (s === null) continue;
    const at = (u) => q.map((v, i) => v + u * a[i]);
    const best = distToRay(at(s), ray);
    for (let u = s - 50; u <= s + 50; u += 0.25) assert.ok(distToRay(at(u), ray) >= best - 1e-9);
  }
  // A ray through q + 7 a (exactly) gives 7; a ray along the axis gives null.
  const q = [1, 2, 3];
  const ray = { origin: [1 + 7, 2 - 10, 3], dir: [0, 1, 0] };
  assert.ok(close(axisParameter(ray, q, [1, 0, 0]), 7));
  assert.equal(axisParameter({ origin: [0, 0, 0], dir: [1, 0, 0] }, q, [1, 0, 0]), null);
});

test("rotateAboutAxis: quarter turns by the right-hand rule, and the rotation matrices", () => {
  const pts = [[0, 1, 0], [0, 0, 1], [1, 0, 0]];
  const o = [0, 0, 0];
  const turn = (p, axis, deg) => {
    const q = [p.slice()];
    rotateAboutAxis(q, [0], axis, deg, o);
    return q[0].map((v) => Math.round(v * 1e12) / 1e12 + 0);
  };
  assert.deepEqual(turn(pts[0], 0, 90), [0, 0, 1]); // y -> z about x
  assert.deepEqual(turn(pts[1], 1, 90), [1, 0, 0]); // z -> x about y
  assert.deepEqual(turn(pts[2], 2, 90), [0, 1, 0]); // x -> y about z
  const r = rng(5);
  for (let k = 0; k < 100; k++) {
    const t = (r() * 720 - 360) * (Math.PI / 180);
    const [c, s] = [Math.cos(t), Math.sin(t)];
    const R = [
      [[1, 0, 0], [0, c, -s], [0, s, c]],
      [[c, 0, s], [0, 1, 0], [-s, 0, c]],
      [[c, -s, 0], [s, c, 0], [0, 0, 1]],
    ];
    const axis = k % 3;
    const center = [r() * 10, r() * 10, r() * 10];
    const p = [r() * 40 - 20, r() * 40 - 20, r() * 40];
    const d = p.map((v, i) => v - center[i]);
    const want = R[axis].map((row, i) => center[i] + row[0] * d[0] + row[1] * d[1] + row[2] * d[2]);
    const got = [p.slice()];
    rotateAboutAxis(got, [0], /** @type {0|1|2} */ (axis), (t * 180) / Math.PI, center);
    assert.ok(near(got[0], want, 1e-9), `${got[0]} vs ${want}`);
  }
});

test("rotateAboutAxis turns a selection about its centroid, leaving the others alone", () => {
  const pts = [[0, 0, 10], [0, 0, 20], [4, 4, 4]];
  rotateAboutAxis(pts, [0, 1], 0, 90);
  // The centroid (0, 0, 15) stays; the offsets (0, 0, ∓5) turn to (0, ±5, 0).
  assert.ok(near(pts[0], [0, 5, 15]) && near(pts[1], [0, -5, 15]));
  assert.deepEqual(pts[2], [4, 4, 4]);
});

/** A flat formation in the x-z plane (its front toward -y), turned by `deg` about z at `c`. */
function flatLogo(deg, c = [10, 20, 40]) {
  const pts = [];
  for (let i = 0; i < 6; i++) for (let j = 0; j < 4; j++) pts.push([c[0] + (i - 2.5) * 3, c[1], c[2] + (j - 1.5) * 3]);
  rotateAboutAxis(pts, pts.map((_, i) => i), 2, deg, c);
  return pts;
}

test("faceAudienceDegrees undoes a turn of a flat formation (audience along -y)", () => {
  for (const deg of [0, 10, -35, 60, 89, -89]) {
    const pts = flatLogo(deg);
    const idx = pts.map((_, i) => i);
    assert.ok(close(faceAudienceDegrees(pts, idx, null), -deg, 1e-6), `${deg}`);
    assert.ok(close(faceAudienceDegrees(pts, idx, [10, -500, 2]), -deg, 1e-6), `${deg}`);
  }
});

test("faceAudienceDegrees turns the front toward an audience camera off to the side", () => {
  // Audience due east of the formation: the front (-y) must end up facing +x, a +90° turn.
  const pts = flatLogo(0);
  const idx = pts.map((_, i) => i);
  const deg = faceAudienceDegrees(pts, idx, [200, 20, 2]);
  assert.ok(close(deg, 90, 1e-6), `${deg}`);
  // After the turn the formation's plane is y-z (x constant) and a second call does nothing.
  rotateAboutAxis(pts, idx, 2, deg);
  assert.ok(pts.every((p) => close(p[0], 10, 1e-9)));
  assert.ok(close(faceAudienceDegrees(pts, idx, [200, 20, 2]), 0, 1e-6));
  // An audience at 45° south-west: atan2 of the direction minus the front's -90°.
  const d = faceAudienceDegrees(flatLogo(0), idx, [10 - 100, 20 - 100, 2]);
  assert.ok(close(d, -45, 1e-6), `${d}`);
});

test("faceAudienceDegrees treats a formation without a plane as facing -y", () => {
  const cube = [];
  for (let i = 0; i < 3; i++) for (let j = 0; j < 3; j++) for (let k = 0; k < 3; k++) cube.push([i * 2, j * 2, 20 + k * 2]);
  const idx = cube.map((_, i) => i);
  assert.equal(faceAudienceDegrees(cube, idx, null), 0);
  assert.ok(close(faceAudienceDegrees(cube, idx, [2, 300, 2]), 180, 1e-9) || close(faceAudienceDegrees(cube, idx, [2, 300, 2]), -180, 1e-9));
  assert.ok(close(faceAudienceDegrees(cube, idx, [-300, 2, 2]), -90, 1e-9));
});

test("audiencePoint: an effect's audience camera, else the geofence's audience side, else none", () => {
  assert.equal(audiencePoint({ settings: {} }), null);
  const fence = { x_min_m: -40, x_max_m: 60, y_min_m: -20, y_max_m: 30 };
  assert.deepEqual(audiencePoint({ settings: { geofence: fence } }), [10, -21, 1.7]);
  const show = { settings: { geofence: fence }, lights: { effects: [{ kind: "solid" }, { kind: "image", camera_m: [5, -80, 2] }] } };
  assert.deepEqual(audiencePoint(show), [5, -80, 2]);
});
