// @ts-check
// Points typed or pasted as text: "x y z [#rrggbb]" lines or a JSON list, and back.

const HEX = /^#[0-9a-fA-F]{6}$/;

/**
 * Parse typed or pasted points.
 * @param {string} text lines of `x y z [#rrggbb]` (spaces, commas or tabs between), or JSON
 *   `[[x, y, z], ...]` / `{"points": [...], "colors": [...]}`
 * @param {string} fallbackColor colour of points that name none
 * @returns {{points: number[][], colors: string[]}}
 * @throws {Error} naming the line (or JSON entry) that is not a point
 */
export function parsePoints(text, fallbackColor) {
  const src = text.trim();
  if (!src) throw new Error("no points given");
  if (src.startsWith("[") || src.startsWith("{")) {
    let data;
    try {
      data = JSON.parse(src);
    } catch (err) {
      throw new Error(`not valid JSON: ${err.message}`);
    }
    const pts = Array.isArray(data) ? data : data.points;
    const cols = Array.isArray(data) ? null : data.colors;
    if (!Array.isArray(pts)) throw new Error('JSON must be a list of [x, y, z] or {"points": [...]}');
    const points = pts.map((p, i) => {
      if (!Array.isArray(p) || p.length !== 3 || !p.every((v) => typeof v === "number" && Number.isFinite(v))) {
        throw new Error(`point ${i}: expected [x, y, z] with finite numbers`);
      }
      return p.slice();
    });
    const colors = points.map((_, i) => (cols && HEX.test(cols[i]) ? cols[i] : fallbackColor));
    return { points, colors };
  }
  const points = [];
  const colors = [];
  src.split(/\r?\n/).forEach((line, i) => {
    const t = line.replace(/#(?![0-9a-fA-F]{6}\b).*$/, "").trim();
    if (!t) return;
    const parts = t.split(/[\s,;]+/).filter(Boolean);
    const color = parts.length === 4 && HEX.test(parts[3]) ? parts.pop() : fallbackColor;
    const nums = parts.map(Number);
    if (nums.length !== 3 || !nums.every(Number.isFinite)) throw new Error(`line ${i + 1}: expected "x y z" or "x y z #rrggbb", got "${line.trim()}"`);
    points.push(nums);
    colors.push(color);
  });
  if (!points.length) throw new Error("no points given");
  return { points, colors };
}

/**
 * A formation's points as text lines `x y z #rrggbb`.
 * @param {number[][]} points
 * @param {string[]} colors
 * @returns {string}
 */
export function formatPoints(points, colors) {
  return points.map((p, i) => `${p.map((v) => +v.toFixed(3)).join(" ")} ${colors[i] || ""}`.trim()).join("\n");
}
