// @ts-check
// Point-set geometry in the canvas views: view axes, arc-length resampling, fit to a count,
// scale and rotate about the centroid.

/**
 * View name -> [horizontal axis, vertical axis, depth axis] (indices into x, y, z). The side view
 * looks from the east (along -x): y to the right, z up. The free 3D view ("3d") has no fixed
 * plane; tools that need one (new points, gradients, rotate in the view) use the front view's.
 */
/** How the editor names the axes (the canvas' legend, the depth field): x east, y north, z up. */
export const AXIS_NAMES = Object.freeze(["x (east)", "y (north)", "z (up)"]);

export const VIEW_AXES = Object.freeze({ front: [0, 2, 1], top: [0, 1, 2], side: [1, 2, 0], "3d": [0, 2, 1] });

function polyLength(poly) {
  let len = 0;
  for (let i = 1; i < poly.length; i++) len += dist(poly[i - 1], poly[i]);
  return len;
}

function dist(a, b) {
  let s = 0;
  for (let c = 0; c < a.length; c++) s += (a[c] - b[c]) ** 2;
  return Math.sqrt(s);
}

/**
 * Split `total` into integers proportional to `weights` (largest remainder).
 * @param {number[]} weights
 * @param {number} total
 * @returns {number[]}
 */
export function largestRemainder(weights, total) {
  const sum = weights.reduce((a, b) => a + b, 0);
  if (sum <= 0) return weights.map((_, i) => (i === 0 ? total : 0));
  const exact = weights.map((w) => (w * total) / sum);
  const base = exact.map(Math.floor);
  let rest = total - base.reduce((a, b) => a + b, 0);
  const order = exact.map((e, i) => [e - base[i], i]).sort((a, b) => b[0] - a[0] || a[1] - b[1]);
  for (let k = 0; rest > 0; k++, rest--) base[order[k % order.length][1]] += 1;
  return base;
}

function samplePolyline(poly, k, closed) {
  if (k <= 0) return [];
  const pts = closed ? [...poly, poly[0]] : poly;
  const cum = [0];
  for (let i = 1; i < pts.length; i++) cum.push(cum[i - 1] + dist(pts[i - 1], pts[i]));
  const len = cum[cum.length - 1];
  if (len === 0) return Array.from({ length: k }, () => pts[0].slice());
  const out = [];
  for (let i = 0; i < k; i++) {
    let s;
    if (closed) s = (i * len) / k;
    else s = k === 1 ? len / 2 : (i * len) / (k - 1);
    let seg = 1;
    while (seg < cum.length - 1 && cum[seg] < s) seg++;
    const t = cum[seg] === cum[seg - 1] ? 0 : (s - cum[seg - 1]) / (cum[seg] - cum[seg - 1]);
    out.push(pts[seg - 1].map((v, c) => v + t * (pts[seg][c] - v)));
  }
  return out;
}

/**
 * Resample polylines to exactly `n` points evenly spaced by arc length, shared among them by length.
 * A polyline whose ends are within `closeTol` is treated as closed (no doubled point at the seam).
 * @param {number[][][]} polylines each a list of points (any dimension)
 * @param {number} n
 * @param {number} [closeTol] metres
 * @returns {number[][]}
 */
export function resamplePolylines(polylines, n, closeTol = 0) {
  const lines = polylines.filter((p) => p.length > 0);
  if (!lines.length || n <= 0) return [];
  const closed = lines.map((p) => p.length > 2 && dist(p[0], p[p.length - 1]) <= closeTol);
  const lens = lines.map((p, i) => polyLength(p) + (closed[i] ? dist(p[p.length - 1], p[0]) : 0));
  const counts = largestRemainder(lens.some((l) => l > 0) ? lens : lens.map(() => 1), n);
  return lines.flatMap((p, i) => samplePolyline(closed[i] ? p.slice(0, -1) : p, counts[i], closed[i]));
}

/**
 * Fit a drawn point set to exactly `n` points: fewer by an even subsample in drawing order,
 * more by resampling the drawing (taken as polylines in point order, split at big jumps) by arc length.
 * Colours follow the nearest source point in drawing order.
 * @param {number[][]} points
 * @param {string[]} colors
 * @param {number} n
 * @returns {{points: number[][], colors: string[]}}
 */
export function fitToCount(points, colors, n) {
  const m = points.length;
  if (m === n) return { points: points.map((p) => p.slice()), colors: colors.slice() };
  if (m === 0) return { points: [], colors: [] };
  if (m > n) {
    const idx = Array.from({ length: n }, (_, i) => Math.floor(((i + 0.5) * m) / n));
    return { points: idx.map((i) => points[i].slice()), colors: idx.map((i) => colors[i]) };
  }
  // Grow: split into runs at jumps bigger than 3x the median step, resample each run by length.
  const steps = [];
  for (let i = 1; i < m; i++) steps.push(dist(points[i - 1], points[i]));
  const sorted = steps.slice().sort((a, b) => a - b);
  const median = sorted.length ? sorted[Math.floor(sorted.length / 2)] : 0;
  const runs = [[0]];
  for (let i = 1; i < m; i++) {
    if (median > 0 && steps[i - 1] > 3 * median) runs.push([i]);
    else runs[runs.length - 1].push(i);
  }
  // Tagged coordinates carry the source index as the 4th component for the colours.
  const lines = runs.map((r) => r.map((i) => [...points[i], i]));
  const weights = lines.map((l) => Math.max(polyLength(l.map((p) => p.slice(0, 3))), median || 1));
  const counts = largestRemainder(weights, n);
  const outP = [];
  const outC = [];
  lines.forEach((line, k) => {
    const pts3 = line.map((p) => p.slice(0, 3));
    const samples = line.length === 1 ? spreadAround(pts3[0], counts[k], median || 1) : samplePolyline(pts3, counts[k], false);
    for (const s of samples) {
      outP.push(s);
      outC.push(colors[nearestIndex(line, s)]);
    }
  });
  return { points: outP, colors: outC };
}

function spreadAround(p, k, step) {
  return Array.from({ length: k }, (_, i) => [p[0] + (i - (k - 1) / 2) * step, p[1], p[2]]);
}

function nearestIndex(line, s) {
  let best = line[0][3];
  let bd = Infinity;
  for (const q of line) {
    const d = (q[0] - s[0]) ** 2 + (q[1] - s[1]) ** 2 + (q[2] - s[2]) ** 2;
    if (d < bd) { bd = d; best = q[3]; }
  }
  return best;
}

/**
 * Centroid of some points.
 * @param {number[][]} points
 * @param {Iterable<number>} indices
 * @returns {number[]}
 */
export function centroid(points, indices) {
  const c = [0, 0, 0];
  let k = 0;
  for (const i of indices) {
    for (let a = 0; a < 3; a++) c[a] += points[i][a];
    k++;
  }
  return k ? c.map((v) => v / k) : c;
}

/**
 * Scale points (in place) about their centroid.
 * @param {number[][]} points
 * @param {number[]} indices
 * @param {number} factor
 */
export function scaleAbout(points, indices, factor) {
  const c = centroid(points, indices);
  for (const i of indices) for (let a = 0; a < 3; a++) points[i][a] = c[a] + (points[i][a] - c[a]) * factor;
}

/**
 * Rotate points (in place) about their centroid in a view's plane, counter-clockwise as seen in the view.
 * @param {number[][]} points
 * @param {number[]} indices
 * @param {number} degrees
 * @param {string} view a key of {@link VIEW_AXES}
 */
export function rotateInView(points, indices, degrees, view) {
  const [u, v] = VIEW_AXES[view];
  const c = centroid(points, indices);
  turnInPlane(points, indices, u, v, degrees, c);
}

/**
 * Turn points (in place) by `degrees` in the plane of coordinates u, v about `c`, from u toward v.
 * @param {number[][]} points
 * @param {number[]} indices
 * @param {number} u
 * @param {number} v
 * @param {number} degrees
 * @param {number[]} c
 */
function turnInPlane(points, indices, u, v, degrees, c) {
  const t = (degrees * Math.PI) / 180;
  const cos = Math.cos(t);
  const sin = Math.sin(t);
  for (const i of indices) {
    const du = points[i][u] - c[u];
    const dv = points[i][v] - c[v];
    points[i][u] = c[u] + du * cos - dv * sin;
    points[i][v] = c[v] + du * sin + dv * cos;
  }
}

/**
 * Round coordinates to millimetres (keeps show files small and stable).
 * @param {number[][]} points
 * @returns {number[][]}
 */
export function roundPoints(points) {
  return points.map((p) => p.map((v) => Math.round(v * 1000) / 1000 + 0));
}

/**
 * Rotate points (in place) about an axis through `center` (default: their centroid) by the right-hand
 * rule: counter-clockwise seen from the axis' positive end, the rotation matrices R_x, R_y, R_z.
 * @param {number[][]} points
 * @param {number[]} indices
 * @param {0|1|2} axis 0 = x, 1 = y, 2 = z
 * @param {number} degrees
 * @param {number[]} [center]
 */
export function rotateAboutAxis(points, indices, axis, degrees, center) {
  const c = center || centroid(points, indices);
  // The plane turned: (y, z) about x, (z, x) about y, (x, y) about z, each in right-handed order.
  const u = (axis + 1) % 3;
  const v = (axis + 2) % 3;
  turnInPlane(points, indices, u, v, degrees, c);
}

/**
 * Where the audience watches from, for turning formations toward it: the first light effect's
 * audience camera (`camera_m`), else a point in front of the geofence's audience side (y below
 * `y_min_m`, the audience looks along +y), else null (the default audience: far away along -y).
 * @param {any} show
 * @returns {number[]|null}
 */
export function audiencePoint(show) {
  const fx = (show && show.lights && show.lights.effects) || [];
  const cam = fx.find((e) => Array.isArray(e.camera_m));
  if (cam) return cam.camera_m.slice(0, 3);
  const g = show && show.settings && show.settings.geofence;
  if (g) return [(g.x_min_m + g.x_max_m) / 2, g.y_min_m - 1, 1.7];
  return null;
}

/**
 * The rotation about the vertical axis (degrees, counter-clockwise from above) that turns a
 * formation's front toward the audience. The front is the horizontal normal of the formation's
 * plane: the minor axis of the points' horizontal (x, y) covariance, the closed-form eigenvector of
 * a symmetric 2x2 matrix, with the sign facing the audience (so the turn is at most 90°). A
 * formation without a clear plane (horizontal spread within 20% in every direction) counts as
 * facing -y, the way flat shapes are authored in the front view.
 * @param {number[][]} points
 * @param {number[]} indices
 * @param {number[]|null} audience a point, or null for the audience far along -y
 * @returns {number} degrees, in (-180, 180]
 */
export function faceAudienceDegrees(points, indices, audience) {
  const c = centroid(points, indices);
  let sxx = 0;
  let syy = 0;
  let sxy = 0;
  for (const i of indices) {
    const dx = points[i][0] - c[0];
    const dy = points[i][1] - c[1];
    sxx += dx * dx;
    syy += dy * dy;
    sxy += dx * dy;
  }
  const want = audience ? [audience[0] - c[0], audience[1] - c[1]] : [0, -1];
  if (Math.hypot(want[0], want[1]) < 1e-9) return 0;
  const tr = sxx + syy;
  const gap = Math.sqrt((sxx - syy) ** 2 + 4 * sxy * sxy);
  const lmin = (tr - gap) / 2;
  const lmax = (tr + gap) / 2;
  /** @type {number[]} */
  let n;
  let signFree = true;
  if (lmax <= 0 || lmin > 0.8 * 0.8 * lmax) {
    n = [0, -1];
    signFree = false;
  } else if (Math.abs(sxy) > 1e-12 * tr) {
    n = [sxy, lmin - sxx]; // (A - lmin I) n = 0, first row
  } else {
    n = sxx <= syy ? [1, 0] : [0, 1];
  }
  if (signFree) {
    const along = n[0] * want[0] + n[1] * want[1];
    // A quarter turn either way is a tie: keep the authored front (-y) on the audience's side.
    const tie = Math.abs(along) < 1e-9 * Math.hypot(n[0], n[1]) * Math.hypot(want[0], want[1]);
    if (tie ? n[1] > 0 : along < 0) n = [-n[0], -n[1]];
  }
  let deg = ((Math.atan2(want[1], want[0]) - Math.atan2(n[1], n[0])) * 180) / Math.PI;
  while (deg <= -180) deg += 360;
  while (deg > 180) deg -= 360;
  return Math.abs(deg) < 1e-9 ? 0 : deg;
}
