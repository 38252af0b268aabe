// @ts-check
// The music lane's arithmetic (no browser APIs, so that node can test it): snapping a time to the
// nearest beat, and folding the server's waveform peaks into one min/max per canvas column.

/**
 * The nearest snap point to `t` within `radius` (seconds), or `t` itself.
 * @param {number} t @param {number[]} points sorted ascending @param {number} radius
 * @returns {number}
 */
export function snapTime(t, points, radius) {
  let lo = 0;
  let hi = points.length;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (points[mid] < t) lo = mid + 1;
    else hi = mid;
  }
  let best = t;
  let bestD = radius;
  for (const i of [lo - 1, lo]) {
    if (i >= 0 && i < points.length && Math.abs(points[i] - t) <= bestD) {
      bestD = Math.abs(points[i] - t);
      best = points[i];
    }
  }
  return best;
}

/**
 * Min and max of the waveform peaks (`[min0, max0, min1, max1, ...]`, -127..127) for each of `width`
 * columns spanning [t0, t1] seconds: `[min, max]` per column in -1..1 (0, 0 where there is no audio).
 * @param {number[]} peaks @param {number} perS buckets per second @param {number} t0 @param {number} t1
 * @param {number} width
 * @returns {Float32Array} 2 * width values
 */
export function columnPeaks(peaks, perS, t0, t1, width) {
  const out = new Float32Array(2 * width);
  const n = peaks.length / 2;
  for (let x = 0; x < width; x++) {
    const a = Math.max(0, Math.floor((t0 + ((t1 - t0) * x) / width) * perS));
    const b = Math.min(n, Math.max(a + 1, Math.floor((t0 + ((t1 - t0) * (x + 1)) / width) * perS)));
    let lo = 0;
    let hi = 0;
    for (let i = a; i < b; i++) {
      lo = Math.min(lo, peaks[2 * i]);
      hi = Math.max(hi, peaks[2 * i + 1]);
    }
    out[2 * x] = lo / 127;
    out[2 * x + 1] = hi / 127;
  }
  return out;
}
