// @ts-check
// Light effects in the browser: the colours of one formation's drones at a show time, for the
// editor's live preview. The same formulas as sim/light (formations/_effects.py documents them),
// evaluated with the drones resting on the formation's points; the exports use the server's.

const MASK64 = (1n << 64n) - 1n;

/** SplitMix64's finaliser on a BigInt (mod 2^64). @param {bigint} x */
function mix64(x) {
  x &= MASK64;
  x ^= x >> 30n;
  x = (x * 0xbf58476d1ce4e5b9n) & MASK64;
  x ^= x >> 27n;
  x = (x * 0x94d049bb133111ebn) & MASK64;
  return x ^ (x >> 31n);
}

/**
 * A uniform number in [0, 1) for (seed, drone, slot), the same as sim.light.uniform_hash.
 * @param {number} seed @param {number} drone @param {number} slot
 */
export function hash01(seed, drone, slot) {
  const h = mix64((mix64((BigInt(seed) << 32n) | BigInt(drone)) + (BigInt(slot) & MASK64)) & MASK64);
  return Number(h >> 11n) / 2 ** 53;
}

/** "#rrggbb" -> [r, g, b] in [0, 1]. @param {string} hex */
export function hexToRgb(hex) {
  const v = parseInt(hex.slice(1), 16);
  return [((v >> 16) & 255) / 255, ((v >> 8) & 255) / 255, (v & 255) / 255];
}

/** [r, g, b] in [0, 1] -> "#rrggbb". @param {number[]} c */
export function rgbToHex(c) {
  return "#" + c.map((v) => Math.round(Math.min(1, Math.max(0, v)) * 255).toString(16).padStart(2, "0")).join("");
}

/** @param {number[][]} stops @param {number} x @param {boolean} wrap */
function gradient(stops, x, wrap) {
  const n = stops.length;
  const k = Math.min(Math.max(Math.floor(x), 0), wrap ? n - 1 : n - 2);
  const w = x - k;
  const k1 = wrap ? (k + 1) % n : k + 1;
  return [0, 1, 2].map((c) => stops[k][c] * (1 - w) + stops[k1][c] * w);
}

/** @param {string} mode @param {number} below @param {number} c @param {number} a */
function blend(mode, below, c, a) {
  let v;
  if (mode === "add") v = below + a * c;
  else if (mode === "multiply") v = below * (1 - a + a * c);
  else if (mode === "max") v = below + a * (Math.max(below, c) - below);
  else v = below + a * (c - below);
  return Math.min(1, Math.max(0, v));
}

/** Fade envelope at t. @param {any} fx @param {number} t */
export function envelope(fx, t) {
  let env = 1;
  if (fx.fade_in_s > 0) env = Math.min(env, (t - fx.start_s) / fx.fade_in_s);
  if (fx.fade_out_s > 0) env = Math.min(env, (fx.end_s - t) / fx.fade_out_s);
  return Math.min(1, Math.max(0, env));
}

/**
 * Colours of drones resting at `points` at show time `t`.
 * @param {any} show the show document (its `lights`, `drones`)
 * @param {string} formationName the formation on screen (for formation targets)
 * @param {number[][]} points (n, 3) positions, metres (drone i at points[i])
 * @param {number[][]} base (n, 3) base colours in [0, 1]
 * @param {number} t show time, seconds
 * @param {(fx: any) => (Array<{w: number, h: number, data: Uint8ClampedArray}>|null)} [images] decoded image
 *   frames of an image effect (RGBA bytes; for a video, the frame at this time), or null while they load
 * @param {{active: (name: string) => boolean, pointRows: (formation: string, indices: number[]) => (Set<number>|null),
 *   positionsAt?: (t: number) => (number[][]|null)}} [ctx] with a plan: whether a formation target applies at t,
 *   the rows (drones) that fly to some points of a formation (default: only the formation on screen, its points
 *   as rows), and the rows' positions at another time when known (chase orders rank by them)
 * @returns {number[][]} (n, 3) colours in [0, 1]
 */
export function evaluateColors(show, formationName, points, base, t, images, ctx) {
  const out = base.map((c) => [c[0], c[1], c[2]]);
  const lights = show && show.lights;
  if (!lights || !Array.isArray(lights.effects)) return out;
  const n = points.length;
  const drones = show.drones || n;
  for (const raw of lights.effects) {
    const fx = { fade_in_s: 0, fade_out_s: 0, blend: "replace", opacity: 1, enabled: true, ...raw };
    if (!fx.enabled || fx.opacity <= 0 || !(t >= fx.start_s && t < fx.end_s)) continue;
    const tg = fx.target || { kind: "all" };
    if (tg.kind === "formation" && !(ctx ? ctx.active(tg.formation) : tg.formation === formationName)) continue;
    // Points of another formation: without a plan the drones that fly there are not known here.
    if (!ctx && tg.kind === "points" && tg.formation !== formationName) continue;
    const a0 = envelope(fx, t) * fx.opacity;
    const e = fx.effect || {};
    const since = t - fx.start_s;
    let only = null;
    if (tg.kind === "drones" || (tg.kind === "points" && !ctx)) only = new Set(tg.indices || []);
    if (tg.kind === "points" && ctx) only = ctx.pointRows(tg.formation, tg.indices || []);
    if (tg.kind === "points" && ctx && !only) continue;
    // The show's groups over the older lights.groups (groups.js allGroups, ShowFile.drone_groups).
    if (tg.kind === "group") only = new Set(({ ...(lights.groups || {}), ...(show.groups || {}) })[tg.group] || []);
    let color = e.color ? hexToRgb(e.color) : [1, 1, 1];
    let frameAlpha = a0;
    if (e.kind === "ramp") {
      const stops = e.colors.map(hexToRgb);
      color = gradient(stops, Math.min(1, Math.max(0, since / (fx.end_s - fx.start_s))) * (stops.length - 1), false);
    } else if (e.kind === "strobe") {
      const x = since * (e.frequency_hz ?? 4);
      if (x - Math.floor(x) >= (e.duty ?? 0.5)) frameAlpha = 0;
    }
    if (frameAlpha <= 0) continue;
    let ranks = null;
    if (e.kind === "chase") {
      const order = e.order || "index";
      if (order === "index") ranks = points.map((_, i) => i / drones);
      else {
        const ax = "xyz".indexOf(order);
        // Ranked where the drones are when the chase starts (the plan's, when known and resting then).
        const at = (ctx && ctx.positionsAt && ctx.positionsAt(fx.start_s)) || points;
        const idx = points.map((_, i) => i).sort((i, j) => at[i][ax] - at[j][ax] || i - j);
        ranks = new Array(n);
        idx.forEach((i, r) => { ranks[i] = r / n; });
      }
    }
    const stops = e.kind === "sweep" ? e.colors.map(hexToRgb) : null;
    const projected = e.kind === "image" || e.kind === "video";
    const frames = projected && images ? images(fx) : null;
    if (projected && !frames) continue;
    for (let i = 0; i < n; i++) {
      if (only && !only.has(i)) continue;
      const p = points[i];
      if (tg.kind === "box" && ![0, 1, 2].every((c) => tg.min_m[c] <= p[c] && p[c] <= tg.max_m[c])) continue;
      if (tg.kind === "plane") {
        const s = [0, 1, 2].reduce((acc, c) => acc + (p[c] - tg.point_m[c]) * tg.normal[c], 0);
        if (s < 0) continue;
      }
      let alpha = frameAlpha;
      let c = color;
      if (e.kind === "sweep" && stops) {
        let along;
        if ((e.mode || "linear") === "linear") {
          const ax = e.axis || [1, 0, 0];
          const norm = Math.hypot(ax[0], ax[1], ax[2]);
          along = (p[0] * ax[0] + p[1] * ax[1] + p[2] * ax[2]) / norm;
        } else {
          const cm = e.center_m || [0, 0, 0];
          along = Math.hypot(p[0] - cm[0], p[1] - cm[1], p[2] - cm[2]);
        }
        const phase = (along - (e.speed_mps ?? 10) * since) / (e.length_m ?? 20);
        c = gradient(stops, (phase - Math.floor(phase)) * stops.length, true);
      } else if (e.kind === "chase" && ranks) {
        let rel = ranks[i] - since / (e.period_s ?? 2);
        rel -= Math.floor(rel);
        alpha *= (e.shape || "pulse") === "wave"
          ? 0.5 * (1 + Math.cos(2 * Math.PI * rel))
          : Math.max(0, 1 - Math.min(rel, 1 - rel) / (e.width ?? 0.1));
      } else if (e.kind === "sparkle") {
        const seed = e.seed ?? 0;
        const x = since / (e.flash_s ?? 0.3) + hash01(seed, i, -1);
        const slot = Math.floor(x);
        const u = x - slot;
        if (hash01(seed, i, slot) >= (e.density ?? 0.2)) continue;
        alpha *= 1 - Math.abs(2 * u - 1);
      } else if (projected && frames) {
        // A video's callback hands the one frame showing at this time.
        const img = e.kind === "video" ? frames[0] : frames[Math.floor(since * (e.fps ?? 10) + 1e-9) % frames.length];
        let x = p[0];
        let z = p[2];
        if (e.camera_m) {
          // Through the audience camera onto the picture's plane y = center_m[1].
          const cam = e.camera_m;
          if (p[1] <= cam[1]) continue;
          const s = (e.center_m[1] - cam[1]) / (p[1] - cam[1]);
          x = cam[0] + s * (p[0] - cam[0]);
          z = cam[2] + s * (p[2] - cam[2]);
        }
        const u = (x - (e.center_m[0] - e.width_m / 2)) / e.width_m;
        const v = (e.center_m[2] + e.height_m / 2 - z) / e.height_m;
        if (!(u >= 0 && u < 1 && v >= 0 && v < 1)) continue;
        const k = 4 * (Math.min(Math.floor(v * img.h), img.h - 1) * img.w + Math.min(Math.floor(u * img.w), img.w - 1));
        c = [img.data[k] / 255, img.data[k + 1] / 255, img.data[k + 2] / 255];
        alpha *= img.data[k + 3] / 255;
      }
      if (alpha <= 0) continue;
      const o = out[i];
      for (let ch = 0; ch < 3; ch++) o[ch] = blend(fx.blend, o[ch], c[ch], alpha);
    }
  }
  return out;
}


/**
 * Formation name -> [[start, end)] windows in which a formation target applies: from the start of the
 * transition into it to the end of its hold (as sim.light's _formation_windows).
 * @param {{segments: {kind: string, label: string, start_s: number, duration_s: number}[]}} plan
 * @returns {Map<string, number[][]>}
 */
export function formationWindows(plan) {
  /** @type {Map<string, number[][]>} */
  const out = new Map();
  let start = null;
  for (const seg of plan.segments) {
    if (seg.kind === "transition") start = seg.start_s;
    else if (seg.kind === "hold") {
      const list = out.get(seg.label) || [];
      list.push([start == null ? seg.start_s : start, seg.start_s + seg.duration_s]);
      out.set(seg.label, list);
      start = null;
    }
  }
  return out;
}

/**
 * Whether a plan summary carries a usable assignment for a show of `drones` drones and `formations` formations.
 * @param {any} plan @param {number} drones @param {number} formations
 */
export function planUsable(plan, drones, formations) {
  return !!(plan && Array.isArray(plan.assignment) && plan.assignment.length === formations
    && plan.drones === drones && plan.assignment.every((/** @type {number[]} */ a) => a.length === drones));
}

/**
 * Colours of formation `k`'s points at show time `t` with the planned assignment: drone i rests on point
 * `plan.assignment[k][i]` and is painted as drone i (its index, groups, sparkle seed), formation targets
 * apply in their planned windows and points targets reach the drones the plan sends there, as the
 * server's evaluator does for a drone holding the formation.
 * @param {any} show the show document
 * @param {number} k the formation on screen
 * @param {number[][]} points (m, 3) its points, metres
 * @param {number[][]} base (m, 3) its points' colours in [0, 1]
 * @param {number} t show time, seconds
 * @param {any} plan a plan summary with `assignment` and `segments` (see planUsable)
 * @param {(fx: any) => any} [images] as for evaluateColors
 * @returns {number[][]} (m, 3) colours per point (points no drone flies to keep their base colour)
 */
export function evaluatePlanned(show, k, points, base, t, plan, images) {
  const goal = plan.assignment[k];
  const names = show.formations.map((/** @type {any} */ f) => f.name);
  const windows = formationWindows(plan);
  /** @type {Map<string, Set<number>|null>} */
  const rowsCache = new Map();
  const ctx = {
    active: (/** @type {string} */ name) => (windows.get(name) || []).some(([a, b]) => t >= a && t < b),
    pointRows: (/** @type {string} */ formation, /** @type {number[]} */ indices) => {
      const key = `${formation}\u0000${indices.join(",")}`;
      if (!rowsCache.has(key)) {
        const j = names.indexOf(formation);
        const want = new Set(indices);
        rowsCache.set(key, j < 0 ? null
          : new Set(plan.assignment[j].map((/** @type {number} */ p, /** @type {number} */ d) => (want.has(p) ? d : -1))
            .filter((/** @type {number} */ d) => d >= 0)));
      }
      return rowsCache.get(key) || null;
    },
    // During a hold every drone rests on its planned point; elsewhere (flying) the preview does not know.
    positionsAt: (/** @type {number} */ s) => {
      const holds = plan.segments.filter((/** @type {any} */ g) => g.kind === "hold");
      const j = holds.findIndex((/** @type {any} */ g) => s >= g.start_s && s <= g.start_s + g.duration_s);
      const f = j >= 0 ? show.formations[j] : null;
      // A subset formation (issue 21): drones that do not fly it (-1) are somewhere the preview does not know.
      if (!f || !Array.isArray(f.points) || f.points.length < Math.max(...plan.assignment[j]) + 1
        || plan.assignment[j].some((/** @type {number} */ p) => p < 0)) return null;
      return plan.assignment[j].map((/** @type {number} */ p) => f.points[p]);
    },
  };
  // Drones not flying this formation (-1, issue 21) are dark and paint no point; they keep their row (index).
  const rows = evaluateColors(show, names[k], goal.map((/** @type {number} */ p) => points[p] || [0, 0, 0]),
    goal.map((/** @type {number} */ p) => base[p] || [0, 0, 0]), t, images, ctx);
  const out = base.map((c) => [c[0], c[1], c[2]]);
  goal.forEach((/** @type {number} */ p, /** @type {number} */ d) => { if (p >= 0) out[p] = rows[d]; });
  return out;
}
