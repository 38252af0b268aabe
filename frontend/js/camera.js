// @ts-check
// The free 3D view's orbit camera: a perspective pinhole looking at a target from a yaw, pitch and
// distance; world point -> screen pixel, screen pixel -> world ray, and the two ray intersections
// a drag needs (a plane facing the camera, an axis line). Pure math, no DOM, so node can test it.

/** @typedef {[number, number, number]} Vec3 */

/** @param {number[]} a @param {number[]} b */
export const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];

/** @param {number[]} a @param {number[]} b @returns {Vec3} */
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];

/** @param {number[]} a @param {number} s @param {number[]} b @returns {Vec3} a + s b */
const addScaled = (a, s, b) => [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]];

/**
 * An orbit camera. Yaw 0, pitch 0 looks along +y (as the audience, the front view) with x to the
 * right and z up; yaw turns the view direction about z from +y toward +x, pitch raises the camera
 * to look down on the target.
 */
export class OrbitCamera {
  constructor() {
    /** @type {Vec3} metres: the point orbited */
    this.target = [0, 0, 40];
    this.yaw_rad = -0.6;
    this.pitch_rad = 0.35;
    this.distance_m = 150;
    this.fov_rad = (50 * Math.PI) / 180; // vertical field of view
    this.width = 800; // CSS pixels
    this.height = 600;
  }

  /** @returns {{eye: Vec3, forward: Vec3, right: Vec3, up: Vec3, focal: number}} the camera frame. */
  frame() {
    const cy = Math.cos(this.yaw_rad);
    const sy = Math.sin(this.yaw_rad);
    const cp = Math.cos(this.pitch_rad);
    const sp = Math.sin(this.pitch_rad);
    /** @type {Vec3} */
    const forward = [sy * cp, cy * cp, -sp];
    /** @type {Vec3} forward x z, normalised: horizontal */
    const right = [cy, -sy, 0];
    /** @type {Vec3} right x forward */
    const up = [sy * sp, cy * sp, cp];
    const eye = addScaled(this.target, -this.distance_m, forward);
    const focal = this.height / 2 / Math.tan(this.fov_rad / 2);
    return { eye, forward, right, up, focal };
  }

  /**
   * World point -> [screen x, screen y, depth along the view direction in metres]. Depth <= 0:
   * behind the camera (the screen position is then meaningless).
   * @param {number[]} p
   * @param {ReturnType<OrbitCamera["frame"]>} [fr] a frame computed once for many points
   * @returns {[number, number, number]}
   */
  project(p, fr = this.frame()) {
    const d = sub(p, fr.eye);
    const z = dot(d, fr.forward);
    const k = fr.focal / z;
    return [this.width / 2 + dot(d, fr.right) * k, this.height / 2 - dot(d, fr.up) * k, z];
  }

  /**
   * Screen pixel -> the world ray through it: origin (the eye) and unit direction.
   * @param {number} sx @param {number} sy
   * @returns {{origin: Vec3, dir: Vec3}}
   */
  ray(sx, sy) {
    const fr = this.frame();
    const a = (sx - this.width / 2) / fr.focal;
    const b = -(sy - this.height / 2) / fr.focal;
    const d = addScaled(addScaled(fr.forward, a, fr.right), b, fr.up);
    const n = Math.hypot(d[0], d[1], d[2]);
    return { origin: fr.eye, dir: [d[0] / n, d[1] / n, d[2] / n] };
  }

  /**
   * Screen pixel -> the world point under it on the plane through `q` facing the camera.
   * @param {number} sx @param {number} sy @param {number[]} q
   * @returns {Vec3|null}
   */
  unprojectAt(sx, sy, q) {
    return rayPlane(this.ray(sx, sy), q, this.frame().forward);
  }
}

/**
 * Where a ray meets a plane (through `q`, normal `n`), or null if parallel or behind the origin.
 * @param {{origin: number[], dir: number[]}} ray
 * @param {number[]} q
 * @param {number[]} n
 * @returns {Vec3|null}
 */
export function rayPlane(ray, q, n) {
  const den = dot(ray.dir, n);
  if (Math.abs(den) < 1e-12) return null;
  const t = dot(sub(q, ray.origin), n) / den;
  if (t < 0) return null;
  return addScaled(ray.origin, t, ray.dir);
}

/**
 * The parameter s of the point q + s a on an axis line (a unit) nearest to a ray: the common
 * perpendicular of two lines (solve both derivative conditions of |q + s a - o - t d|^2). Null when
 * the ray runs along the axis.
 * @param {{origin: number[], dir: number[]}} ray
 * @param {number[]} q
 * @param {number[]} a unit vector
 * @returns {number|null}
 */
export function axisParameter(ray, q, a) {
  const w0 = sub(q, ray.origin);
  const b = dot(a, ray.dir);
  const c = dot(ray.dir, ray.dir);
  const den = c - b * b;
  if (Math.abs(den) < 1e-9) return null;
  return (b * dot(ray.dir, w0) - c * dot(a, w0)) / den;
}
