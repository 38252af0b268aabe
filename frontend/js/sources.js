// @ts-check
// Formation sources and whole-formation operations: shape presets, text, image, SVG and mesh uploads
// (through the formation endpoints), scale, rotate, fit to the drone count, spacing repair.

import * as api from "./api.js";
import { toast } from "./dialogs.js";
import { setError } from "./errors.js";
import { VIEW_AXES, fitToCount, rotateInView, roundPoints, scaleAbout } from "./geometry.js";
import { closePairs, repairSpacing, roundKeepingSpacing } from "./spacing.js";
import { targetIndices } from "./colors.js";
import { formatPoints, parsePoints } from "./pointstext.js";
import { flyingCount } from "./groups.js";

// The plane a new formation is built in: the one the designer is looking at (the 3D view builds in the front plane).
const PLANE_OF_VIEW = { front: "xz", top: "xy", side: "yz" };

/** The one kind-specific parameter offered for a shape preset. */
const SHAPE_PARAM = {
  polygon: { key: "sides", label: "Sides", value: 6, integer: true, min: 3 },
  star: { key: "points", label: "Tips", value: 5, integer: true, min: 2 },
  filled_star: { key: "points", label: "Tips", value: 5, integer: true, min: 2 },
  helix: { key: "turns", label: "Turns", value: 3, integer: false, min: 0.1 },
};

/** Uploaded files of this page session by name, to make their formations again at another count. */
const uploads = new Map();

/** A request body without the count and spacing (what a formation's `source.params` keeps). */
function withoutCount(body) {
  const { n: _n, min_spacing_m: _d, ...rest } = body;
  return rest;
}

/**
 * The label of the first shown number field of `form` left empty that the request needs (a field with a
 * placeholder, such as the mesh size's "fit", may stay empty), or null: an empty field reads as 0.
 * @param {HTMLFormElement} form @returns {string|null}
 */
export function emptyNumberField(form) {
  for (const el of form.querySelectorAll("input[type=number]")) {
    const input = /** @type {HTMLInputElement} */ (el);
    if (input.value.trim() !== "" || input.placeholder || input.closest("[hidden]")) continue;
    const label = input.id ? form.querySelector(`label[for="${CSS.escape(input.id)}"]`) : null;
    return label ? label.textContent.trim() : input.name;
  }
  return null;
}

/**
 * Say the browser's own range check next to `form` (error key `key`) when it blocks a submit: no submit event
 * comes then, so a message from the last answer (say "16 drones do not fit at 10 m") stayed beside the browser's
 * bubble about another value. `invalid` does not bubble: listened for in the capture phase.
 * @param {HTMLFormElement} form @param {string} key
 */
export function sayInvalid(form, key) {
  form.addEventListener("invalid", (e) => {
    const input = /** @type {HTMLInputElement} */ (e.target);
    const label = input.id ? form.querySelector(`label[for="${CSS.escape(input.id)}"]`) : null;
    setError(key, `${label ? label.textContent.trim() : input.name}: ${input.validationMessage}`);
  }, true);
}

/**
 * A cheap fingerprint of a point set: count and rounded coordinate sums. A formation whose points
 * still have the fingerprint stored in its `source` was not edited by hand since it was made.
 * @param {number[][]} points
 */
export function fingerprint(points) {
  const sum = [0, 0, 0];
  for (const p of points) for (let c = 0; c < 3; c++) sum[c] += p[c];
  return `${points.length}:${sum.map((v) => v.toFixed(2)).join(",")}`;
}

/**
 * True when formation `f`'s name is not one the designer typed: the editor's default ("Formation 3")
 * or the name its last import gave it (kept in `source.name`), so a new import may rename it.
 * @param {{name: string, source?: any}} f
 */
export function autoNamed(f) {
  return /^Formation \d+$/.test(f.name) || (f.source != null && f.source.name != null && f.source.name === f.name);
}

/**
 * `base`, or `base 2`, `base 3`, ... : the first not taken by another formation of the show than `self`.
 * @param {{formations: {name: string}[]}} show @param {string} base @param {object} self
 */
function freeName(show, base, self) {
  const names = new Set(show.formations.filter((f) => f !== self).map((f) => f.name));
  if (!names.has(base)) return base;
  for (let k = 2; ; k++) if (!names.has(`${base} ${k}`)) return `${base} ${k}`;
}

/**
 * Apply an import to formation `k` inside an edit: its points and colours, its source, and the
 * name the server suggests after the source (file stem, text, shape) unless the designer named it.
 * @param {import("./state.js").EditorState} st @param {number} k
 * @param {{points: number[][], colors: string[], name?: string}} res
 * @param {any} made the source record (kind, params, file)
 */
function applyImport(st, k, res, made) {
  const f = st.show.formations[k];
  f.points = roundKeepingSpacing(res.points, st.show.settings.min_distance_m);
  f.colors = res.colors;
  const named = res.name && autoNamed(f);
  if (named) f.name = freeName(st.show, /** @type {string} */ (res.name), f);
  f.source = { ...made, ...(named ? { name: f.name } : {}), fingerprint: fingerprint(f.points) };
  if (k === st.current) st.selection = new Set();
}

/** Wires the source forms and the transform buttons to the open show. */
export class Sources {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {import("./canvas.js").CanvasView} view
   */
  constructor(state, view) {
    this.state = state;
    this.view = view;
    const kindSelect = /** @type {HTMLSelectElement} */ (document.getElementById("shape-kind"));
    const paramRow = document.getElementById("shape-param-row");
    const paramInput = /** @type {HTMLInputElement} */ (document.getElementById("shape-param"));
    const showParam = () => {
      const spec = SHAPE_PARAM[kindSelect.value];
      paramRow.hidden = !spec;
      if (!spec) return;
      document.getElementById("shape-param-label").textContent = spec.label;
      paramInput.setAttribute("aria-label", spec.label);
      paramInput.value = String(spec.value);
      paramInput.step = spec.integer ? "1" : "any";
      paramInput.min = String(spec.min);
    };
    kindSelect.addEventListener("change", showParam);
    showParam();
    this._form("form-shape", "shape", (fd) => {
      const kind = String(fd.get("kind"));
      const spec = SHAPE_PARAM[kind];
      return {
        kind,
        params: spec ? { [spec.key]: spec.integer ? Math.round(Number(fd.get("param"))) : Number(fd.get("param")) } : {},
        size_m: Number(fd.get("size_m")),
        plane: String(fd.get("plane")),
        center_m: this._center(Number(fd.get("z"))),
        color: String(fd.get("color")),
      };
    });
    this._form("form-text", "text", (fd) => ({
      text: String(fd.get("text")),
      height_m: Number(fd.get("height_m")),
      plane: PLANE_OF_VIEW[this.view.view],
      center_m: this._center(Number(fd.get("z"))),
      color: String(fd.get("color")),
    }));
    this._form("form-upload", "upload", (fd) => ({
      width_m: Number(fd.get("width_m")),
      plane: PLANE_OF_VIEW[this.view.view],
      center_m: this._center(Number(fd.get("z"))),
    }));
    this._meshForm();
    const num = (id) => Number(/** @type {HTMLInputElement} */ (document.getElementById(id)).value);
    document.getElementById("btn-scale").addEventListener("click", () => this.scale(num("scale-input") / 100));
    document.getElementById("btn-rotate").addEventListener("click", () => this.rotate(num("rotate-input")));
    document.getElementById("btn-fit-n").addEventListener("click", () => this.fitToN());
    const pointsForm = document.getElementById("form-points");
    const pointsText = /** @type {HTMLTextAreaElement} */ (document.getElementById("points-input"));
    pointsForm.addEventListener("submit", (e) => {
      e.preventDefault();
      this.typedPoints(pointsText.value, false);
    });
    document.getElementById("btn-points-add").addEventListener("click", () => this.typedPoints(pointsText.value, true));
    document.getElementById("btn-points-copy").addEventListener("click", () => {
      const f = this.state.formation;
      if (f) pointsText.value = formatPoints(f.points, f.colors);
    });
    document.getElementById("btn-repair").addEventListener("click", () => this.repair());
  }

  /** Centre of a new drawing: the middle of the canvas horizontally, at height z, at the canvas depth. */
  _center(z) {
    const [u] = this.view.toWorldUV(this.view.width / 2, this.view.height / 2);
    const p = [0, 0, 0];
    const [a, , d] = VIEW_AXES[this.view.view];
    p[a] = Math.round(u);
    p[d] = this.view.depth;
    p[2] = z;
    if (this.view.view === "top") p[1] = Math.round(this.view.toWorldUV(this.view.width / 2, this.view.height / 2)[1]);
    return p;
  }

  /**
   * The smallest size (to 2 %) at which a source yields all the drones at the minimum distance,
   * by bisection over the formation endpoint (the size that fails is the lower bound).
   * @param {"shape"|"text"|"image"|"svg"} source endpoint name @param {any} body request body @param {string} sizeKey
   * @param {File} [file] @param {number} [maxN] the largest N that fits at body[sizeKey], if known
   * @returns {Promise<number|null>} metres, or null if none up to 64x the size fits
   */
  async _sizeToFit(source, body, sizeKey, file, maxN) {
    const fits = async (size) => {
      try {
        await api.buildFormation(source, { ...body, [sizeKey]: size }, file);
        return true;
      } catch (err) {
        const maxN = err.problems && err.problems[0] ? err.problems[0].max_n : null;
        if (maxN === 0) throw err; // nothing to place drones on at any size: the server's message says why
        if (maxN != null) return false;
        // Refused for another reason at this size (e.g. it reaches below the ground around the
        // current centre): the drones fit at the spacing; placing it is the next message's job.
        if (err.status === 422) return true;
        throw err;
      }
    };
    let hi = body[sizeKey] * (maxN ? Math.max(1.05, body.n / maxN) : 1.5);
    let lo = 0;
    while (!(await fits(hi))) {
      lo = hi;
      hi *= 2;
      if (hi > body[sizeKey] * 64) return null;
    }
    if (lo === 0) lo = (await fits(body[sizeKey])) ? 0 : body[sizeKey];
    if (lo === 0) lo = body[sizeKey] / 64;
    while (hi / lo > 1.02) {
      const mid = Math.sqrt(lo * hi);
      if (await fits(mid)) hi = mid;
      else lo = mid;
    }
    return Math.ceil(hi * 10) / 10;
  }

  _form(id, key, params) {
    const form = /** @type {HTMLFormElement} */ (document.getElementById(id));
    const sizeKey = { shape: "size_m", text: "height_m", upload: "width_m" }[key];
    const request = (fd) => {
      const st = this.state;
      const body = { ...params(fd), n: st.show.drones, min_spacing_m: st.show.settings.min_distance_m };
      let source = key;
      let file;
      if (key === "upload") {
        file = /** @type {File} */ (fd.get("file"));
        if (!file || !file.name) throw new Error("Choose a PNG, JPEG or SVG file.");
        source = /svg/i.test(file.type) || /\.svg$/i.test(file.name) ? "svg" : "image";
      }
      return { body, source, file };
    };
    sayInvalid(form, key);
    const fitButton = /** @type {HTMLButtonElement|null} */ (form.querySelector(".fit-size"));
    fitButton?.addEventListener("click", async () => {
      setError(key, "");
      if (!this.state.formation) return setError(key, "Open or create a show first.");
      const empty = emptyNumberField(form);
      if (empty) return setError(key, `${empty}: enter a number.`);
      fitButton.disabled = true;
      try {
        const { body, source, file } = request(new FormData(form));
        const size = await this._sizeToFit(source, body, sizeKey, file);
        if (size == null) return setError(key, `${body.n} drones do not fit even at 64 times this size: use fewer drones or a smaller minimum distance.`);
        /** @type {HTMLInputElement} */ (form.elements.namedItem(sizeKey)).value = String(size);
        // Keep the resized drawing above the altitude floor: its centre at least half the size up.
        const zInput = /** @type {HTMLInputElement|null} */ (form.elements.namedItem("z"));
        const settings = this.state.show.settings;
        const floor = settings.min_altitude_m ?? 0;
        if (zInput && sizeKey !== "width_m" && Number(zInput.value) < size / 2 + floor) {
          zInput.value = String(Math.min(Math.ceil(size / 2 + floor), settings.max_altitude_m - size / 2));
        }
        toast(`${size} m fits ${body.n} drones at ${body.min_spacing_m} m`);
      } catch (err) {
        setError(key, err.message);
      } finally {
        fitButton.disabled = false;
      }
    });
    form.addEventListener("submit", async (e) => {
      e.preventDefault();
      setError(key, "");
      const st = this.state;
      if (!st.formation) return setError(key, "Open or create a show first.");
      const empty = emptyNumberField(form);
      if (empty) return setError(key, `${empty}: enter a number.`);
      const fd = new FormData(form);
      const body = { ...params(fd), n: st.show.drones, min_spacing_m: st.show.settings.min_distance_m };
      let source = key;
      let file;
      if (key === "upload") {
        file = /** @type {File} */ (fd.get("file"));
        if (!file || !file.name) return setError(key, "Choose a PNG, JPEG or SVG file.");
        source = /svg/i.test(file.type) || /\.svg$/i.test(file.name) ? "svg" : "image";
      }
      const button = /** @type {HTMLButtonElement} */ (form.querySelector("button[type=submit]"));
      button.disabled = true;
      button.setAttribute("aria-busy", "true");
      const target = st.formation;
      try {
        const res = await api.buildFormation(source, body, file);
        const label = key === "shape" ? `Shape: ${body.kind}` : key === "text" ? `Text "${body.text.slice(0, 20)}"` : `From ${file.name}`;
        const made = { kind: source, params: withoutCount(body) };
        if (file) {
          made.file = file.name;
          uploads.set(file.name, file);
        }
        const where = this._replace(key, label, target, res, made);
        if (where == null) return;
        toast(`${label}${where}: ${res.points.length} points, nearest pair ${res.min_spacing_m != null ? res.min_spacing_m.toFixed(2) + " m" : "—"}`);
      } catch (err) {
        const p = err.problems && err.problems[0];
        let msg = err.message;
        // max_n 0: nothing to place drones on at any size (blank text, a black image, an SVG without paths);
        // the server's message says which.
        if (p && p.max_n != null && p.max_n > 0) {
          // Say once what fits now and what size would fit them all.
          const size = await this._sizeToFit(source, body, sizeKey, file, p.max_n).catch(() => null);
          msg = `${body.n} drones do not fit at ${body[sizeKey]} m with ${body.min_spacing_m} m between them: at most ${p.max_n} fit.` +
            (size != null ? ` ${size} m fits all ${body.n} ("Size to fit").` : " Use fewer drones or a smaller minimum distance.");
        }
        setError(key, msg);
      } finally {
        button.disabled = false;
        button.removeAttribute("aria-busy");
      }
    });
  }

  /**
   * Replace the points of formation `target` (the one current when the server was asked) with what it built.
   * The designer may have moved on meanwhile: the points go to that formation wherever it now is, not to the
   * current one; when it is gone (deleted, undone, another show opened) nothing changes and the form says so.
   * @param {string} key the form's error slot
   * @param {string} label the undo step's name
   * @param {any} target the formation object the request was made for
   * @param {{points: number[][], colors: string[], name?: string}} res the server's formation
   * @param {any} made the formation's `source` (without its fingerprint)
   * @returns {string|null} "" when it was the current formation, ` → "name"` for another one, null when gone
   */
  _replace(key, label, target, res, made) {
    const st = this.state;
    const k = st.show ? st.show.formations.indexOf(target) : -1;
    if (k < 0) {
      setError(key, `Not applied: "${target.name}" changed while the points were being made (undone, deleted `
        + "or another show opened); apply it again.");
      return null;
    }
    st.edit(label, () => applyImport(st, k, res, made));
    if (k !== st.current) return ` → "${st.show.formations[k].name}"`;
    this.view.fit();
    return "";
  }

  /**
   * The mesh / point-cloud import: all drones over the surface, vertices or volume of an uploaded
   * OBJ/PLY/STL/glTF/GLB, or a Skybrush CSV / XYZ point file; an empty size asks the server for the
   * smallest size that keeps the minimum distance.
   */
  _meshForm() {
    const form = /** @type {HTMLFormElement} */ (document.getElementById("form-mesh"));
    sayInvalid(form, "mesh");
    form.addEventListener("submit", async (e) => {
      e.preventDefault();
      setError("mesh", "");
      const st = this.state;
      if (!st.formation) return setError("mesh", "Open or create a show first.");
      const empty = emptyNumberField(form);
      if (empty) return setError("mesh", `${empty}: enter a number.`);
      const fd = new FormData(form);
      const file = /** @type {File} */ (fd.get("file"));
      if (!file || !file.name) return setError("mesh", "Choose a mesh or point file.");
      const size = String(fd.get("size_m") || "").trim();
      /** @type {any} */
      const body = {
        mode: String(fd.get("mode")),
        center_m: this._center(Number(fd.get("z"))),
        n: st.show.drones,
        min_spacing_m: st.show.settings.min_distance_m,
      };
      if (size) body.size_m = Number(size);
      const button = /** @type {HTMLButtonElement} */ (form.querySelector("button[type=submit]"));
      button.disabled = true;
      button.setAttribute("aria-busy", "true");
      const target = st.formation;
      try {
        const res = /** @type {any} */ (await api.buildFormation(/** @type {any} */ ("mesh"), body, file));
        uploads.set(file.name, file);
        const label = `From ${file.name}`;
        const where = this._replace("mesh", label, target, res,
          { kind: "mesh", params: withoutCount(body), file: file.name });
        if (where == null) return;
        toast(`${label}${where}: ${res.points.length} points, ${res.size_m != null ? res.size_m.toFixed(1) + " m across" : ""}`);
      } catch (err) {
        const p = err.problems && err.problems[0];
        let msg = err.message;
        if (p && p.max_n != null) {
          // An empty size asked for the smallest size that fits: the mesh itself holds too few points (its vertices).
          const at = body.size_m != null ? `at ${body.size_m} m` : `on the ${body.mode} of ${file.name}`;
          msg = `${body.n} drones do not fit ${at} with ${body.min_spacing_m} m between them: at most ${p.max_n} fit.` +
            (p.fit_size_m != null ? ` ${Math.ceil(p.fit_size_m * 10) / 10} m fits all ${body.n} (or leave the size empty).` : "");
        }
        setError("mesh", msg);
      } finally {
        button.disabled = false;
        button.removeAttribute("aria-busy");
      }
    });
  }

  /**
   * Replace the formation with typed points, or add them to it.
   * @param {string} text see {@link parsePoints}
   * @param {boolean} add
   */
  typedPoints(text, add) {
    setError("points", "");
    const st = this.state;
    if (!st.formation) return;
    let parsed;
    try {
      parsed = parsePoints(text, /** @type {HTMLInputElement} */ (document.getElementById("color-pick")).value);
    } catch (err) {
      setError("points", err.message);
      return;
    }
    st.edit(add ? `Add ${parsed.points.length} typed points` : `${parsed.points.length} typed points`, () => {
      const f = st.formation;
      f.points = add ? [...f.points, ...parsed.points] : parsed.points;
      f.colors = add ? [...f.colors, ...parsed.colors] : parsed.colors;
      st.selection = new Set();
    });
  }

  /**
   * Scale the selection (or the formation) about its centre.
   * @param {number} factor
   */
  scale(factor) {
    setError("transform", "");
    if (!(factor > 0)) return setError("transform", "Scale must be a positive percentage.");
    const idx = targetIndices(this.state);
    if (!idx.length) return;
    this.state.edit(`Scale ${Math.round(factor * 100)}%`, () => {
      const pts = this.state.formation.points;
      scaleAbout(pts, idx, factor);
      this.state.formation.points = roundKeepingSpacing(pts, this.state.show.settings.min_distance_m, idx);
    });
  }

  /**
   * Rotate the selection (or the formation) about its centre in the view's plane.
   * @param {number} degrees counter-clockwise
   */
  rotate(degrees) {
    setError("transform", "");
    if (!Number.isFinite(degrees)) return setError("transform", "Enter an angle in degrees.");
    const idx = targetIndices(this.state);
    if (!idx.length) return;
    this.state.edit(`Rotate ${degrees}°`, () => {
      const pts = this.state.formation.points;
      rotateInView(pts, idx, degrees, this.view.view);
      this.state.formation.points = roundKeepingSpacing(pts, this.state.show.settings.min_distance_m, idx);
    });
  }

  /**
   * Fit the current formation to exactly the drone count: made again from its source (text, shape,
   * image) when it was not edited since, else the drawing resampled along its strokes and spread
   * apart; never into a formation that breaks the minimum distance (a message says what fits).
   */
  async fitToN() {
    setError("transform", "");
    const st = this.state;
    if (!st.formation) return;
    if (!st.formation.points.length) return setError("transform", "The formation is empty: draw or place some points first.");
    const msg = await this.fitFormation(st.current);
    if (msg) setError("transform", msg);
    else toast(`${st.show.drones} points`);
  }

  /** Fit every formation with fewer points than drones (see {@link fitFormation}); returns the messages. */
  async fitAll() {
    const st = this.state;
    const msgs = [];
    for (let k = 0; k < st.show.formations.length; k++) {
      // A subset formation (issue 21) needs points for the drones that fly it only (as the settings' prompt counts).
      if (st.show.formations[k].points.length >= flyingCount(st.show, st.show.formations[k])) continue;
      const m = await this.fitFormation(k);
      if (m) msgs.push(`"${st.show.formations[k].name}": ${m}`);
    }
    setError("transform", msgs.join(" "));
    return msgs;
  }

  /**
   * Fit formation `k` to the drone count (one undo step).
   * @param {number} k
   * @returns {Promise<string>} "" when done, else what is wrong and what would fit
   */
  async fitFormation(k) {
    const st = this.state;
    const f = st.show.formations[k];
    const n = flyingCount(st.show, f);
    const d = st.show.settings.min_distance_m;
    const src = f.source;
    const file = src && src.file ? uploads.get(src.file) : undefined;
    if (src && src.fingerprint === fingerprint(f.points) && (!src.file || file)) {
      const body = { ...src.params, n, min_spacing_m: d };
      try {
        const res = await api.buildFormation(src.kind, body, file);
        st.edit(`Fit "${f.name}" to ${n} drones`, () => {
          const g = st.show.formations[k];
          g.points = roundKeepingSpacing(res.points, d);
          g.colors = res.colors;
          g.source = { ...src, fingerprint: fingerprint(g.points) };
          if (k === st.current) st.selection = new Set();
        });
        return "";
      } catch (err) {
        const p = err.problems && err.problems[0];
        if (!p || p.max_n == null) return err.message;
        const sizeKey = ["size_m", "height_m", "width_m"].find((key) => key in src.params);
        const size = sizeKey ? await this._sizeToFit(src.kind, body, sizeKey, file, p.max_n).catch(() => null) : null;
        return `${n} drones do not fit at ${sizeKey ? `${src.params[sizeKey]} m` : "this size"} with ${d} m between them: at most ${p.max_n} fit.` +
          (size != null ? ` Make it ${size} m to fit all ${n}.` : "");
      }
    }
    // A drawing (or an edited formation): resample it, spread it, and keep it only if it is spaced.
    const plane = /** @type {[number, number]} */ (VIEW_AXES[this.view.view].slice(0, 2));
    const fit = fitToCount(f.points, f.colors, n);
    const fixed = repairSpacing(fit.points, d, { plane });
    if (Number.isFinite(fixed.achieved)) {
      // The largest count that keeps the spacing by resampling alone (bisection), and the scale for all.
      let lo = 1;
      let hi = n;
      while (hi - lo > 1) {
        const mid = (lo + hi) >> 1;
        if (closePairs(fitToCount(f.points, f.colors, mid).points, d).pairs.length) hi = mid;
        else lo = mid;
      }
      const pct = this._scaleToFit(f.points, f.colors, n, d, n / lo);
      const u = plane[0];
      const xs = f.points.map((q) => q[u]);
      const width = (Math.max(...xs) - Math.min(...xs)) * (pct / 100);
      const where = pct ? `scale it by ${pct}% (to about ${width.toFixed(1)} m wide, "Scale" in Transform) first` : "draw it larger first";
      return `${n} points do not fit this drawing ${d} m apart (at most ${lo} do): ${where}, or use fewer drones.`;
    }
    st.edit(`Fit "${f.name}" to ${n} drones`, () => {
      const g = st.show.formations[k];
      g.points = roundPoints(fixed.points);
      g.colors = fit.colors;
      delete g.source;
      if (k === st.current) st.selection = new Set();
    });
    return "";
  }

  /**
   * The smallest whole percentage that makes a drawing hold `n` points `d` apart when resampled
   * (bisection on the scale: a longer stroke spaces the same count further apart), 0 if none up to
   * 64 times the guess.
   * @param {number[][]} points
   * @param {string[]} colors
   * @param {number} n
   * @param {number} d
   * @param {number} guess a scale factor to start from (n over the count that fits now)
   * @returns {number}
   */
  _scaleToFit(points, colors, n, d, guess) {
    const all = points.map((_, i) => i);
    const fits = (/** @type {number} */ factor) => {
      const scaled = points.map((q) => q.slice());
      scaleAbout(scaled, all, factor);
      return !closePairs(fitToCount(scaled, colors, n).points, d).pairs.length;
    };
    let lo = 1;
    let hi = Math.max(guess, 1.01);
    while (!fits(hi)) {
      lo = hi;
      hi *= 2;
      if (hi > 64 * guess) return 0;
    }
    for (let it = 0; it < 30 && hi - lo > 1e-4; it++) {
      const mid = (lo + hi) / 2;
      if (fits(mid)) hi = mid;
      else lo = mid;
    }
    // Whole percent, rounded up, and checked: what the user types into Scale must work.
    let pct = Math.ceil(100 * hi);
    while (!fits(pct / 100) && pct < 6400 * guess) pct++;
    return pct;
  }

  /** Push apart points closer than the minimum distance. */
  repair() {
    setError("transform", "");
    const st = this.state;
    const f = st.formation;
    if (!f) return;
    const d = st.show.settings.min_distance_m;
    const res = repairSpacing(f.points, d, { plane: /** @type {[number, number]} */ (VIEW_AXES[this.view.view].slice(0, 2)) });
    if (!res.moved) {
      toast("Spacing is fine: every pair is at least the minimum distance apart");
      return;
    }
    st.edit("Repair spacing", () => {
      f.points = roundPoints(res.points);
    });
    if (Number.isFinite(res.achieved)) setError("transform", `Some points are still ${res.achieved.toFixed(2)} m apart (< ${d} m): spread the drawing or use fewer drones.`);
    else toast(`Moved ${res.moved} points apart`);
  }
}
