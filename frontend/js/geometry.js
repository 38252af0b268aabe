// @ts-check
// Point-set geometry in the canvas views: view axes, arc-length resampling, fit to a count,
// scale and rotate about the centroid.

/** View name -> [horizontal axis, vertical axis, depth axis] (indices into x, y, z). */
export const VIEW_AXES = Object.freeze({ front: [0, 2, 1], top: [0, 1, 2] });

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
 * @param {"front"|"top"} view
 */
export function rotateInView(points, indices, degrees, view) {
  const [u, v] = VIEW_AXES[view];
  const c = centroid(points, indices);
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
