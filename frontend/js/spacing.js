// @ts-check
// Minimum-distance checks and repair with a uniform grid of buckets (cell = the minimum
// distance), so each point is only compared with points in its own and the 26 neighbouring cells.

/** A uniform grid of point indices keyed by exact integer cell numbers. */
class Grid {
  constructor(points, cell) {
    this.cell = cell;
    let lo = [Infinity, Infinity, Infinity];
    let hi = [-Infinity, -Infinity, -Infinity];
    for (const p of points) {
      for (let c = 0; c < 3; c++) {
        const k = Math.floor(p[c] / cell);
        if (k < lo[c]) lo[c] = k;
        if (k > hi[c]) hi[c] = k;
      }
    }
    // One spare cell on each side so that neighbour lookups never wrap into another row.
    this.lo = lo.map((v) => v - 1);
    this.nx = hi[0] - lo[0] + 3;
    this.ny = hi[1] - lo[1] + 3;
    this.map = new Map();
    for (let i = 0; i < points.length; i++) {
      const key = this.key(points[i]);
      let bucket = this.map.get(key);
      if (!bucket) this.map.set(key, (bucket = []));
      bucket.push(i);
    }
  }

  key(p, dx = 0, dy = 0, dz = 0) {
    const ix = Math.floor(p[0] / this.cell) - this.lo[0] + dx;
    const iy = Math.floor(p[1] / this.cell) - this.lo[1] + dy;
    const iz = Math.floor(p[2] / this.cell) - this.lo[2] + dz;
    return ix + this.nx * (iy + this.ny * iz);
  }
}

/**
 * Every pair of points closer than `minDistance` (strictly, with a 1e-9 m tolerance).
 * @param {number[][]} points (x, y, z) metres
 * @param {number} minDistance metres (> 0)
 * @param {Iterable<number>} [only] if given, only pairs with at least one of these points
 * @returns {{close: Set<number>, pairs: Array<[number, number, number]>, minDistance: number}}
 *   indices involved, the pairs (i < j, distance) and the smallest distance found below the limit (Infinity if none)
 */
export function closePairs(points, minDistance, only) {
  const close = new Set();
  /** @type {Array<[number, number, number]>} */
  const pairs = [];
  let smallest = Infinity;
  if (!(minDistance > 0) || points.length < 2) return { close, pairs, minDistance: smallest };
  const grid = new Grid(points, minDistance);
  const limit2 = (minDistance - 1e-9) ** 2;
  const subset = only ? new Set(only) : null;
  const queried = subset ? [...subset] : points.keys();
  for (const i of queried) {
    const p = points[i];
    for (let dx = -1; dx <= 1; dx++) {
      for (let dy = -1; dy <= 1; dy++) {
        for (let dz = -1; dz <= 1; dz++) {
          const bucket = grid.map.get(grid.key(p, dx, dy, dz));
          if (!bucket) continue;
          for (const j of bucket) {
            // Each pair once: i < j, or (with a subset) j outside it.
            if (j === i || (j < i && (!subset || subset.has(j)))) continue;
            const q = points[j];
            const d2 = (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2;
            if (d2 < limit2) {
              close.add(i);
              close.add(j);
              const d = Math.sqrt(d2);
              pairs.push(i < j ? [i, j, d] : [j, i, d]);
              if (d < smallest) smallest = d;
            }
          }
        }
      }
    }
  }
  return { close, pairs, minDistance: smallest };
}

/**
 * Nearest-pair distance of a point set (grid search growing the cell until a pair is found).
 * @param {number[][]} points
 * @returns {number} metres (Infinity for fewer than 2 points)
 */
export function nearestPairDistance(points) {
  if (points.length < 2) return Infinity;
  let lo = Infinity;
  let hi = -Infinity;
  for (const p of points) for (const c of p) { lo = Math.min(lo, c); hi = Math.max(hi, c); }
  let cell = Math.max((hi - lo) / Math.cbrt(points.length) / 2, 1e-6);
  for (let k = 0; k < 60; k++) {
    const r = closePairs(points, cell);
    if (r.pairs.length) return r.minDistance;
    cell *= 2;
  }
  return Infinity;
}

/**
 * Push apart points closer than `minDistance` (each close pair moves apart by half its overlap per
 * iteration; points that are far enough apart never move). Coincident points separate along `plane`.
 * @param {number[][]} points metres (not modified)
 * @param {number} minDistance metres
 * @param {{maxIter?: number, plane?: [number, number]}} [opts] plane: the two axes to spread coincident points in
 * @returns {{points: number[][], achieved: number, moved: number}} the new points, the smallest distance left
 *   (Infinity if all pairs are far enough apart) and how many points moved
 */
export function repairSpacing(points, minDistance, opts = {}) {
  const maxIter = opts.maxIter ?? 200;
  const [a1, a2] = opts.plane ?? [0, 2];
  const pts = points.map((p) => p.slice());
  const target = minDistance * 1.001;
  const moved = new Set();
  let seed = 12345;
  const rand = () => ((seed = (seed * 1103515245 + 12345) % 2147483648) / 2147483648);
  let active = null; // after the first pass only moved points can be too close to something
  for (let iter = 0; iter < maxIter; iter++) {
    const { pairs, close } = closePairs(pts, target, active ?? undefined);
    if (!pairs.length) break;
    active = close;
    const shift = pts.map(() => [0, 0, 0]);
    for (const [i, j, d] of pairs) {
      let dir;
      if (d < 1e-9) {
        const t = rand() * 2 * Math.PI;
        dir = [0, 0, 0];
        dir[a1] = Math.cos(t);
        dir[a2] = Math.sin(t);
      } else {
        dir = [0, 1, 2].map((c) => (pts[j][c] - pts[i][c]) / d);
      }
      const half = (target - d) / 2;
      for (let c = 0; c < 3; c++) {
        shift[i][c] -= dir[c] * half;
        shift[j][c] += dir[c] * half;
      }
      moved.add(i);
      moved.add(j);
    }
    for (let i = 0; i < pts.length; i++) for (let c = 0; c < 3; c++) pts[i][c] += shift[i][c];
  }
  const left = closePairs(pts, minDistance);
  return { points: pts, achieved: left.pairs.length ? left.minDistance : Infinity, moved: moved.size };
}

/**
 * `points` with those at `indices` (default: all) rounded to millimetres (the show file stays short), unless the
 * rounding brings a pair closer than `minDistance` that was not: a formation source places its closest pair at
 * exactly the minimum distance (the smallest size that fits), a grid drawn at the minimum distance has every
 * neighbour there, and moving each coordinate by up to 0.5 mm moves a distance by up to √3 mm, which the save
 * refuses (a draft). Then the points stay as they are (a move or turn keeps every distance).
 * @param {number[][]} points @param {number} minDistance metres @param {Iterable<number>} [indices]
 * @returns {number[][]} new arrays
 */
export function roundKeepingSpacing(points, minDistance, indices) {
  const rounded = points.map((p) => p.slice());
  for (const i of indices ?? points.keys()) rounded[i] = rounded[i].map((v) => Math.round(v * 1000) / 1000 + 0);
  const n = points.length;
  const before = new Set(closePairs(points, minDistance).pairs.map(([i, j]) => i * n + j));
  const created = closePairs(rounded, minDistance).pairs.some(([i, j]) => !before.has(i * n + j));
  return created ? points.map((p) => p.slice()) : rounded;
}
