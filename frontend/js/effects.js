// @ts-check
// The light-effects panel: add, edit, reorder and remove the show's effects (show.lights.effects,
// bottom of the stack first), and preview them on the canvas at a show time (scrub or play).

import * as api from "./api.js";
import { setError } from "./errors.js";
import { allGroups } from "./groups.js";
import { markRange } from "./settings.js";
import { evaluateColors, evaluatePlanned, hexToRgb, planUsable, rgbToHex } from "./lighteval.js";

/** Quiet time after the last edit before the 3D view is sent the effects, milliseconds. */
const VIEWER_DEBOUNCE_MS = 250;

export const KINDS = ["solid", "ramp", "sweep", "chase", "sparkle", "strobe", "image", "video"];
/** Widest a video frame is kept for the preview, pixels (as the server keeps it). */
const VIDEO_WIDTH_PX = 192;
/** Latest time an effect field takes, seconds (formations/_effects.py MAX_TIME_S: one day). */
const MAX_TIME_S = "86400";
const BLENDS = ["replace", "add", "multiply", "max"];
const TARGETS = ["all", "formation", "points", "drones", "group", "box", "plane"];

/** A new effect of `kind` starting at `start` seconds. @param {string} kind @param {number} start */
export function newEffect(kind, start) {
  const s = Math.max(0, Math.round(start * 10) / 10);
  /** @type {Record<string, any>} */
  const kinds = {
    solid: { kind, color: "#ffffff" },
    ramp: { kind, colors: ["#ff0000", "#0000ff"] },
    sweep: { kind, colors: ["#ff0000", "#00ff00", "#0000ff"], mode: "linear", axis: [1, 0, 0], center_m: [0, 0, 0],
      length_m: 20, speed_mps: 10 },
    chase: { kind, color: "#ffffff", order: "index", shape: "pulse", period_s: 2, width: 0.1 },
    sparkle: { kind, color: "#ffffff", density: 0.2, flash_s: 0.3, seed: 0 },
    strobe: { kind, color: "#ffffff", frequency_hz: 4, duty: 0.5 },
    image: { kind, frames: [], fps: 10, center_m: [0, 0, 50], width_m: 60, height_m: 40 },
    video: { kind, video: "", center_m: [0, 0, 50], width_m: 60, height_m: 40 },
  };
  return { name: "", start_s: s, end_s: s + 10, fade_in_s: 0, fade_out_s: 0, blend: "replace", opacity: 1,
    target: { kind: "all" }, effect: kinds[kind] };
}

/** "1, 2, 3" -> [1, 2, 3] (null when not exactly `n` finite numbers, or any count when n = 0). */
function parseNumbers(text, n = 3) {
  const v = String(text).split(/[\s,;]+/).filter(Boolean).map(Number);
  if ((n && v.length !== n) || v.some((x) => !Number.isFinite(x))) return null;
  return v;
}

/** A data URL's bytes as a Blob (decoded here: the CSP lets fetch reach only the server). @param {string} url */
function dataUrlBlob(url) {
  const comma = url.indexOf(",");
  const bin = atob(url.slice(comma + 1));
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  return new Blob([bytes], { type: url.slice(5, url.indexOf(";")) });
}

/** Read a PNG/JPEG file as a data URL. @param {File} file @returns {Promise<string>} */
function readDataUrl(file) {
  return new Promise((resolve, reject) => {
    const r = new FileReader();
    r.onload = () => resolve(String(r.result));
    r.onerror = () => reject(r.error);
    r.readAsDataURL(file);
  });
}

export class EffectsPanel {
  /**
   * @param {HTMLElement} root the panel's body
   * @param {import("./state.js").EditorState} state
   * @param {{redraw: () => void, toast?: (msg: string, opts?: any) => void, plan?: () => any,
   *   viewer?: () => ({token: string, lights: number}|null)}} hooks `plan`: the last fresh check's plan summary (its assignment
   *   places the drones in the preview); `viewer`: the open 3D preview page's token and the revision of the
   *   effects it paints (unsaved effects are painted there)
   */
  constructor(root, state, hooks) {
    this.root = root;
    this.state = state;
    this.hooks = hooks;
    this.selected = -1;
    this.time = 0;
    this.previewing = false;
    this.playing = false;
    /** @type {Map<string, {w: number, h: number, data: Uint8ClampedArray}|null>} decoded image frames */
    this.images = new Map();
    /** @type {Map<string, {el: HTMLVideoElement, frame: any, busy: boolean}>} preview videos by data URL */
    this.videos = new Map();
    this._sentVersion = -1;
    this._sentRev = 0;
    /** @type {any} */
    this._sentShow = null;
    /** @type {{plan: any, show: any, version: number, out: any}|null} the last fit of the check's plan */
    this._planFit = null;
    /** @type {string|null} */
    this._sentToken = null;
    this._sendTimer = 0;
    this._build();
    // The music lane's playhead (scrub or play, with the sound) moves the preview while it is on.
    state.addEventListener("playhead", (/** @type {any} */ e) => {
      if (this.previewing && !this.playing) this.seek(e.detail.time_s);
    });
    state.addEventListener("change", (/** @type {any} */ e) => {
      if (e.detail.kind === "live" || e.detail.kind === "selection") {
        return;
      }
      this.render();
      this.scheduleViewer();
    });
  }

  /** The last fresh check's plan summary when its assignment fits the show, else null. */
  get plan() {
    const s = this.state.show;
    const plan = this.hooks.plan ? this.hooks.plan() : null;
    if (!s || !planUsable(plan, s.drones, s.formations.length)) return null;
    const c = this._planFit;
    if (c && c.plan === plan && c.show === s && c.version === this.state.version) return c.out;
    // A check of an older version still places the drones while its formations are these (names, enough
    // points); after a formation is renamed, added or cut down the preview is approximate until the next check.
    const holds = plan.segments.filter((/** @type {any} */ g) => g.kind === "hold");
    const fits = s.formations.every((/** @type {any} */ f, /** @type {number} */ k) => holds[k] && holds[k].label === f.name
      && plan.assignment[k].every((/** @type {number} */ p) => p < f.points.length));
    this._planFit = { plan, show: s, version: this.state.version, out: fits ? plan : null };
    return this._planFit.out;
  }

  /** Send the effects to the 3D preview shortly (edits in a burst send once). */
  scheduleViewer() {
    clearTimeout(this._sendTimer);
    this._sendTimer = window.setTimeout(() => { this.sendToViewer(); }, VIEWER_DEBOUNCE_MS);
  }

  /**
   * Paint the current (maybe unsaved) effects in this tab's 3D preview (POST /api/viewer/{token}/lights).
   * @param {boolean} [force] send even when unchanged since the last send
   * @returns {Promise<boolean>} whether the viewer took them
   */
  async sendToViewer(force = false) {
    const v = this.hooks.viewer ? this.hooks.viewer() : null;
    const s = this.state.show;
    if (!v || !s) return false;
    const token = v.token;
    // Unchanged since the last send (the version moves with every edit; a new viewer page has a new token; a
    // reloaded show paints its saved effects, revision 0, until it is sent these again).
    const version = this.state.version;
    if (!force && version === this._sentVersion && s === this._sentShow && this._sentToken === token
      && (v.lights !== 0 || this._sentRev === 0)) return false;
    this._sentVersion = version;
    this._sentShow = s;
    this._sentToken = token;
    try {
      const res = await api.request("POST", `/api/viewer/${encodeURIComponent(token)}/lights`,
        { json: { lights: s.lights || null, groups: s.groups || null } });
      this._sentRev = res.revision;
      setError("lights", "");
      return true;
    } catch (err) {
      // A refused design waits for the next edit; anything else (the page reloading, the show switching) retries.
      if (err instanceof api.ApiError && (err.status === 422 || err.status === 413)) {
        setError("lights", `The 3D view cannot show these effects: ${err.message}`);
      }
      else this._sentVersion = -1;
      return false;
    }
  }

  /** @returns {any[]} the effect stack of the open show (read-only view). */
  get effects() {
    const s = this.state.show;
    return (s && s.lights && s.lights.effects) || [];
  }

  /** Show length for the time slider: the planned length when a check is known, else holds plus a guess per
   * transition; at least the last effect's end. */
  get duration() {
    const s = this.state.show;
    if (!s) return 60;
    const plan = this.hooks.plan ? this.hooks.plan() : null;
    if (plan && plan.duration_s > 0) return Math.ceil(Math.max(plan.duration_s, ...this.effects.map((e) => e.end_s || 0)));
    const holds = s.formations.reduce((acc, f) => acc + (f.hold_s || 0) + (f.transition_s || 15), 30);
    return Math.ceil(Math.max(holds, ...this.effects.map((e) => e.end_s || 0)));
  }

  _build() {
    this.root.innerHTML = `
      <div class="row"><label class="inline"><input type="checkbox" id="fx-preview" aria-label="Preview the light effects on the canvas"> Preview at</label>
        <input id="fx-time" type="range" min="0" max="60" step="0.04" value="0" aria-label="Preview time, seconds">
        <output id="fx-time-out" for="fx-time">0.0 s</output>
        <button id="fx-play" type="button" aria-label="Play the effect preview">▶</button>
        <span id="fx-approx" class="hint" hidden title="Check the show to preview with the planned assignment">approximate: drones on points in order</span></div>
      <div class="row"><select id="fx-kind" aria-label="Kind of effect to add">${KINDS.map((k) => `<option value="${k}">${k}</option>`).join("")}</select>
        <button id="fx-add" type="button" aria-label="Add a light effect">Add effect</button></div>
      <ol id="fx-list" class="fx-list" aria-label="Light effects, bottom of the stack first"></ol>
      <div id="fx-form" class="fx-form"></div>
      <p class="field-error" data-error-for="lights" role="alert"></p>`;
    const q = (/** @type {string} */ sel) => /** @type {any} */ (this.root.querySelector(sel));
    this.$time = q("#fx-time");
    this.$timeOut = q("#fx-time-out");
    this.$list = q("#fx-list");
    this.$form = q("#fx-form");
    q("#fx-preview").addEventListener("change", (/** @type {any} */ e) => { this.setPreview(e.target.checked); });
    this.$preview = q("#fx-preview");
    this.$time.addEventListener("input", () => { this.seek(Number(this.$time.value)); });
    q("#fx-play").addEventListener("click", () => (this.playing ? this.pause() : this.play()));
    this.$play = q("#fx-play");
    q("#fx-add").addEventListener("click", () => this.add(q("#fx-kind").value));
    this.$approx = q("#fx-approx");
  }

  /** The drones flying to the selected points of the formation on screen (the plan's, else drone i on point i). */
  selectedDrones() {
    const st = this.state;
    if (!st.show || !st.selection.size) return [];
    const sel = [...st.selection];
    const plan = this.plan;
    if (plan) {
      const want = new Set(sel);
      return plan.assignment[st.current].map((/** @type {number} */ p, /** @type {number} */ d) => (want.has(p) ? d : -1))
        .filter((/** @type {number} */ d) => d >= 0);
    }
    return sel.filter((i) => i < st.show.drones).sort((a, b) => a - b);
  }

  /**
   * A drone group was just made (the groups panel, groups.js): the selected effect, if any, targets it.
   * @param {string} name
   */
  targetGroup(name) {
    const s = this.state.show;
    const k = this.selected;
    if (!s || !s.lights || k < 0 || !s.lights.effects[k]) return;
    this.state.edit(`Effect targets group "${name}"`, () => {
      const list = [...s.lights.effects];
      list[k] = { ...list[k], target: { kind: "group", group: name } };
      s.lights = { ...s.lights, effects: list };
    });
  }

  /** Turn the canvas preview on or off. @param {boolean} on */
  setPreview(on) {
    this.previewing = on;
    this.$preview.checked = on;
    if (!on) this.pause();
    this.hooks.redraw();
  }

  /** @param {number} t */
  seek(t) {
    this.time = Math.max(0, t);
    this.$time.max = String(this.duration);
    this.$time.value = String(this.time);
    this.$timeOut.textContent = `${this.time.toFixed(1)} s`;
    if (!this.previewing) this.setPreview(true);
    else this.hooks.redraw();
  }

  play() {
    if (this.playing) return;
    this.playing = true;
    this.$play.textContent = "❚❚";
    this.$play.setAttribute("aria-label", "Pause the effect preview");
    if (!this.previewing) this.setPreview(true);
    let last = performance.now();
    const step = (/** @type {number} */ now) => {
      if (!this.playing) return;
      const dur = this.duration;
      let t = this.time + (now - last) / 1000;
      last = now;
      if (t > dur) t = 0;
      this.seek(t);
      requestAnimationFrame(step);
    };
    requestAnimationFrame(step);
  }

  pause() {
    this.playing = false;
    if (this.$play) {
      this.$play.textContent = "▶";
      this.$play.setAttribute("aria-label", "Play the effect preview");
    }
  }

  /**
   * Colours of formation `f` with the effects at the preview time (hex per point), or null when not previewing.
   * @param {any} f
   * @param {string[]} base hex colours per point
   */
  colorsFor(f, base) {
    if (!this.previewing || !this.state.show) return null;
    const k = this.state.show.formations.indexOf(f);
    const plan = this.plan;
    this.$approx.hidden = !!plan;
    if (plan && k >= 0) {
      const out = evaluatePlanned(this.state.show, k, f.points, base.map(hexToRgb), this.time, plan, (fx) => this._frames(fx));
      return out.map(rgbToHex);
    }
    const n = Math.min(f.points.length, this.state.show.drones);
    const pts = f.points.slice(0, n);
    const rgb = base.slice(0, n).map(hexToRgb);
    const out = evaluateColors(this.state.show, f.name, pts, rgb, this.time, (fx) => this._frames(fx));
    return out.map(rgbToHex).concat(base.slice(n));
  }

  /** The frame of a video effect showing at the preview time (a one-element list), or null while it seeks.
   * @param {any} fx */
  _videoFrame(fx) {
    const url = fx.effect.video;
    if (!url) return null;
    let v = this.videos.get(url);
    if (!v) {
      const el = document.createElement("video");
      el.muted = true;
      el.preload = "auto";
      const entry = { el, frame: /** @type {any} */ (null), busy: false };
      el.addEventListener("seeked", () => {
        const w = Math.min(VIDEO_WIDTH_PX, el.videoWidth || VIDEO_WIDTH_PX);
        const h = Math.max(1, Math.round((w * (el.videoHeight || 1)) / (el.videoWidth || 1)));
        const c = document.createElement("canvas");
        c.width = w;
        c.height = h;
        const ctx = /** @type {CanvasRenderingContext2D} */ (c.getContext("2d"));
        ctx.drawImage(el, 0, 0, w, h);
        entry.frame = { w, h, data: ctx.getImageData(0, 0, w, h).data };
        entry.busy = false;
        this.hooks.redraw();
      });
      el.addEventListener("loadedmetadata", () => this.hooks.redraw());
      el.addEventListener("error", () => { entry.busy = false; });
      // The editor's CSP allows media from blob: URLs, not data: ones.
      el.src = URL.createObjectURL(dataUrlBlob(url));
      this.videos.set(url, entry);
      v = entry;
    }
    const dur = v.el.duration;
    if (Number.isFinite(dur) && dur > 0 && !v.busy) {
      const t = (((this.time - fx.start_s) % dur) + dur) % dur;
      if (!v.frame || Math.abs(v.el.currentTime - t) > 0.04) {
        v.busy = true;
        v.el.currentTime = t;
      }
    }
    return v.frame ? [v.frame] : null;
  }

  /** Decoded frames of an image effect, or null while any is loading. @param {any} fx */
  _frames(fx) {
    if (fx.effect && fx.effect.kind === "video") return this._videoFrame(fx);
    const urls = (fx.effect && fx.effect.frames) || [];
    const out = [];
    for (const url of urls) {
      if (!this.images.has(url)) {
        this.images.set(url, null);
        const img = new Image();
        img.onload = () => {
          const c = document.createElement("canvas");
          c.width = img.naturalWidth;
          c.height = img.naturalHeight;
          const ctx = /** @type {CanvasRenderingContext2D} */ (c.getContext("2d"));
          ctx.drawImage(img, 0, 0);
          this.images.set(url, { w: c.width, h: c.height, data: ctx.getImageData(0, 0, c.width, c.height).data });
          this.hooks.redraw();
        };
        img.src = url;
      }
      const d = this.images.get(url);
      if (!d) return null;
      out.push(d);
    }
    return out.length ? out : null;
  }

  /** Add an effect of `kind` at the preview time (one undo step). @param {string} kind */
  add(kind) {
    const s = this.state.show;
    if (!s) return;
    this.state.edit(`Add ${kind} effect`, () => {
      s.lights = { groups: {}, effects: [], ...(s.lights || {}) };
      s.lights.effects = [...s.lights.effects, newEffect(kind, this.time)];
      this.selected = s.lights.effects.length - 1;
    });
  }

  /** @param {number} k */
  remove(k) {
    const s = this.state.show;
    this.state.edit("Remove effect", () => {
      s.lights.effects = s.lights.effects.filter((/** @type {any} */ _, /** @type {number} */ j) => j !== k);
      if (!s.lights.effects.length && !Object.keys(s.lights.groups || {}).length) delete s.lights;
      this.selected = -1;
    });
  }

  /** Move effect k by `by` places in the stack. @param {number} k @param {number} by */
  move(k, by) {
    const s = this.state.show;
    const j = k + by;
    if (j < 0 || j >= this.effects.length) return;
    this.state.edit("Reorder effects", () => {
      const list = [...s.lights.effects];
      [list[k], list[j]] = [list[j], list[k]];
      s.lights.effects = list;
      this.selected = j;
    });
  }

  /**
   * Change effect k (one undo step): `fn` edits a copy of it.
   * @param {number} k @param {string} label @param {(fx: any) => (void|boolean)} fn
   */
  change(k, label, fn) {
    const s = this.state.show;
    const before = JSON.stringify(s.lights.effects[k]);
    const copy = JSON.parse(before);
    // No step for a change that changes nothing (a field's change event fires again on blur).
    if (fn(copy) === false || JSON.stringify(copy) === before) return;
    this.state.edit(label, () => {
      const list = [...s.lights.effects];
      list[k] = copy;
      s.lights.effects = list;
    });
  }

  render() {
    const fx = this.effects;
    if (this.selected >= fx.length) this.selected = fx.length - 1;
    this.$time.max = String(this.duration);
    this.$list.replaceChildren(...fx.map((e, k) => {
      const li = document.createElement("li");
      li.className = k === this.selected ? "selected" : "";
      const label = document.createElement("button");
      label.type = "button";
      label.className = "fx-label";
      label.textContent = `${e.name || e.effect.kind} · ${e.start_s}–${e.end_s} s · ${e.blend || "replace"}`;
      label.setAttribute("aria-label", `Edit effect ${k + 1}: ${label.textContent}`);
      label.addEventListener("click", () => { this.selected = k; this.render(); });
      const mk = (/** @type {string} */ text, /** @type {string} */ aria, /** @type {() => void} */ fn) => {
        const b = document.createElement("button");
        b.type = "button";
        b.textContent = text;
        b.setAttribute("aria-label", aria);
        b.addEventListener("click", fn);
        return b;
      };
      li.append(label, mk("↑", `Move effect ${k + 1} down the stack`, () => this.move(k, -1)),
        mk("↓", `Move effect ${k + 1} up the stack`, () => this.move(k, 1)),
        mk("×", `Remove effect ${k + 1}`, () => this.remove(k)));
      return li;
    }));
    this._renderForm();
    this.$approx.hidden = !!this.plan;
    if (this.previewing) this.hooks.redraw();
  }

  _renderForm() {
    const k = this.selected;
    const form = this.$form;
    form.replaceChildren();
    if (k < 0 || !this.effects[k]) return;
    const fx = this.effects[k];
    const e = fx.effect;
    /** @param {string} label @param {HTMLElement} input */
    const row = (label, input) => {
      const div = document.createElement("div");
      div.className = "row";
      const l = document.createElement("label");
      l.textContent = label;
      input.setAttribute("aria-label", `Effect ${label}`);
      div.append(l, input);
      form.append(div);
      return input;
    };
    /**
     * @param {string} label @param {any} value @param {(v: number, fx: any) => void} set
     * @param {object} [attrs] the input's properties (min, max, step) and `exclusive`: its strict bounds ("min", "max", "min max")
     */
    const num = (label, value, set, attrs = {}) => {
      const input = document.createElement("input");
      input.type = "number";
      input.step = "any";
      input.value = String(value ?? "");
      const { exclusive, ...props } = /** @type {any} */ (attrs);
      Object.assign(input, props);
      if (exclusive) input.dataset.exclusive = exclusive;
      // Outside the show file's limit: applied (the save keeps a draft) and marked at once, in the editor's words.
      const err = document.createElement("span");
      err.className = "field-error";
      err.setAttribute("role", "alert");
      input.addEventListener("change", () => {
        const v = Number(input.value);
        if (input.value === "" || !Number.isFinite(v)) return;
        markRange(input, v, err);
        this.change(k, `Effect ${label}`, (c) => set(v, c));
      });
      row(label, input).after(err);
      if (value != null && Number.isFinite(Number(value))) markRange(input, Number(value), err);
      return input;
    };
    /** @param {string} label @param {string[]} options @param {string} value @param {(v: string, fx: any) => void} set */
    const sel = (label, options, value, set) => {
      const s = document.createElement("select");
      s.innerHTML = options.map((o) => `<option value="${o}"${o === value ? " selected" : ""}>${o}</option>`).join("");
      s.addEventListener("change", () => this.change(k, `Effect ${label}`, (c) => set(s.value, c)));
      return row(label, s);
    };
    /** @param {string} label @param {number[]} value @param {(v: number[], fx: any) => void} set */
    const vec = (label, value, set) => {
      const input = document.createElement("input");
      input.type = "text";
      input.value = (value || []).join(", ");
      input.placeholder = "x, y, z";
      input.addEventListener("change", () => {
        const v = parseNumbers(input.value);
        if (!v) { this.hooks.toast?.(`${label}: three numbers, x, y, z`, { error: true }); return; }
        this.change(k, `Effect ${label}`, (c) => set(v, c));
      });
      return row(label, input);
    };
    /** @param {string} label @param {string} value @param {(v: string, fx: any) => void} set */
    const color = (label, value, set) => {
      const input = document.createElement("input");
      input.type = "color";
      input.value = value;
      input.addEventListener("change", () => this.change(k, `Effect ${label}`, (c) => set(input.value, c)));
      return row(label, input);
    };
    const name = document.createElement("input");
    name.type = "text";
    name.maxLength = 200;
    name.value = fx.name || "";
    name.addEventListener("change", () => this.change(k, "Rename effect", (c) => { c.name = name.value; }));
    row("name", name);
    num("start (s)", fx.start_s, (v, c) => { c.start_s = v; }, { min: "0", max: MAX_TIME_S });
    num("end (s)", fx.end_s, (v, c) => { c.end_s = v; }, { min: "0", max: MAX_TIME_S, exclusive: "min" });
    num("fade in (s)", fx.fade_in_s ?? 0, (v, c) => { c.fade_in_s = v; }, { min: "0", max: MAX_TIME_S });
    num("fade out (s)", fx.fade_out_s ?? 0, (v, c) => { c.fade_out_s = v; }, { min: "0", max: MAX_TIME_S });
    sel("blend", BLENDS, fx.blend || "replace", (v, c) => { c.blend = v; });
    num("opacity", fx.opacity ?? 1, (v, c) => { c.opacity = v; }, { min: "0", max: "1" });
    const tg = fx.target || { kind: "all" };
    sel("target", TARGETS, tg.kind, (v, c) => {
      const names = this.state.show.formations.map((/** @type {any} */ f) => f.name);
      /** @type {Record<string, any>} */
      const fresh = {
        all: { kind: "all" },
        formation: { kind: "formation", formation: this.state.formation ? this.state.formation.name : names[0] },
        // The selection is of formation points: the drones that fly there are the plan's to choose.
        points: { kind: "points", formation: this.state.formation ? this.state.formation.name : names[0],
          indices: this.state.selection.size ? [...this.state.selection].sort((a, b) => a - b) : [0] },
        drones: { kind: "drones", indices: [0] },
        group: { kind: "group", group: Object.keys(allGroups(this.state.show))[0] || "group" },
        box: { kind: "box", min_m: [-10, -10, 0], max_m: [10, 10, 100] },
        plane: { kind: "plane", point_m: [0, 0, 0], normal: [1, 0, 0] },
      };
      c.target = fresh[v];
    });
    if (tg.kind === "formation") {
      sel("formation", this.state.show.formations.map((/** @type {any} */ f) => f.name), tg.formation,
        (v, c) => { c.target.formation = v; });
    } else if (tg.kind === "drones" || tg.kind === "points") {
      const what = tg.kind === "drones" ? "drones" : "points";
      if (tg.kind === "points") {
        sel("of formation", this.state.show.formations.map((/** @type {any} */ f) => f.name), tg.formation,
          (v, c) => { c.target.formation = v; });
      }
      const input = document.createElement("input");
      input.type = "text";
      input.value = tg.indices.join(", ");
      input.addEventListener("change", () => {
        const v = parseNumbers(input.value, 0);
        if (!v || !v.length || v.some((x) => x < 0 || !Number.isInteger(x))) {
          this.hooks.toast?.(`${what}: indices like 0, 4, 8`, { error: true });
          return;
        }
        this.change(k, `Effect ${what}`, (c) => { c.target.indices = v; });
      });
      row(what, input);
      if (tg.kind === "points") {
        const use = document.createElement("button");
        use.type = "button";
        use.textContent = "Use selection";
        use.setAttribute("aria-label", "Target the selected points of the current formation");
        use.addEventListener("click", () => {
          if (!this.state.selection.size || !this.state.formation) return;
          const name = this.state.formation.name;
          const idx = [...this.state.selection].sort((a, b) => a - b);
          this.change(k, "Effect points", (c) => { c.target = { kind: "points", formation: name, indices: idx }; });
        });
        form.append(use);
      }
    } else if (tg.kind === "group") {
      const input = document.createElement("input");
      input.type = "text";
      input.value = tg.group;
      input.addEventListener("change", () => this.change(k, "Effect group", (c) => { c.target.group = input.value; }));
      row("group", input);
    } else if (tg.kind === "box") {
      vec("box min (m)", tg.min_m, (v, c) => { c.target.min_m = v; });
      vec("box max (m)", tg.max_m, (v, c) => { c.target.max_m = v; });
    } else if (tg.kind === "plane") {
      vec("plane point (m)", tg.point_m, (v, c) => { c.target.point_m = v; });
      vec("plane normal", tg.normal, (v, c) => { c.target.normal = v; });
    }
    if ("color" in e) color("colour", e.color, (v, c) => { c.effect.color = v; });
    if (Array.isArray(e.colors)) {
      e.colors.forEach((hex, j) => color(`colour ${j + 1}`, hex, (v, c) => { c.effect.colors[j] = v; }));
      const add = document.createElement("button");
      add.type = "button";
      add.textContent = "+ colour";
      add.addEventListener("click", () => this.change(k, "Add colour", (c) => { c.effect.colors.push("#ffffff"); }));
      const del = document.createElement("button");
      del.type = "button";
      del.textContent = "− colour";
      del.addEventListener("click", () => this.change(k, "Remove colour", (c) => {
        if (c.effect.colors.length <= 2) return false;
        c.effect.colors.pop();
      }));
      const div = document.createElement("div");
      div.className = "row";
      div.append(add, del);
      form.append(div);
    }
    if (e.kind === "sweep") {
      sel("mode", ["linear", "radial"], e.mode || "linear", (v, c) => { c.effect.mode = v; });
      if ((e.mode || "linear") === "linear") vec("axis", e.axis || [1, 0, 0], (v, c) => { c.effect.axis = v; });
      else vec("centre (m)", e.center_m || [0, 0, 0], (v, c) => { c.effect.center_m = v; });
      num("length (m)", e.length_m ?? 20, (v, c) => { c.effect.length_m = v; }, { min: "0", max: "100000", exclusive: "min" });
      num("speed (m/s)", e.speed_mps ?? 10, (v, c) => { c.effect.speed_mps = v; });
    } else if (e.kind === "chase") {
      sel("order", ["index", "x", "y", "z"], e.order || "index", (v, c) => { c.effect.order = v; });
      sel("shape", ["pulse", "wave"], e.shape || "pulse", (v, c) => { c.effect.shape = v; });
      num("period (s)", e.period_s ?? 2, (v, c) => { c.effect.period_s = v; }, { min: "0.02", max: MAX_TIME_S });
      num("width", e.width ?? 0.1, (v, c) => { c.effect.width = v; }, { min: "0", max: "1", exclusive: "min" });
    } else if (e.kind === "sparkle") {
      num("density", e.density ?? 0.2, (v, c) => { c.effect.density = v; }, { min: "0", max: "1" });
      num("flash (s)", e.flash_s ?? 0.3, (v, c) => { c.effect.flash_s = v; }, { min: "0.02", max: "60" });
      num("seed", e.seed ?? 0, (v, c) => { c.effect.seed = Math.round(v); }, { min: "0", max: "2147483647", step: "1" });
    } else if (e.kind === "strobe") {
      num("frequency (Hz)", e.frequency_hz ?? 4, (v, c) => { c.effect.frequency_hz = v; }, { min: "0", max: "25", exclusive: "min" });
      num("duty", e.duty ?? 0.5, (v, c) => { c.effect.duty = v; }, { min: "0", max: "1", exclusive: "min max" });
    } else if (e.kind === "image") {
      const file = document.createElement("input");
      file.type = "file";
      file.accept = "image/png,image/jpeg";
      file.multiple = true;
      file.addEventListener("change", async () => {
        const files = [...(file.files || [])].sort((a, b) => a.name.localeCompare(b.name));
        if (!files.length) return;
        const urls = await Promise.all(files.map(readDataUrl));
        this.change(k, "Effect images", (c) => { c.effect.frames = urls; });
      });
      row(`images (${(e.frames || []).length})`, file);
      num("fps", e.fps ?? 10, (v, c) => { c.effect.fps = v; }, { min: "0", max: "60", exclusive: "min" });
      vec("centre (m)", e.center_m, (v, c) => { c.effect.center_m = v; });
      num("width (m)", e.width_m, (v, c) => { c.effect.width_m = v; }, { min: "0", max: "100000", exclusive: "min" });
      num("height (m)", e.height_m, (v, c) => { c.effect.height_m = v; }, { min: "0", max: "100000", exclusive: "min" });
      this._cameraField(k, e);
    } else if (e.kind === "video") {
      const file = document.createElement("input");
      file.type = "file";
      file.accept = "video/mp4,video/webm,video/ogg,video/quicktime";
      file.addEventListener("change", async () => {
        const f = (file.files || [])[0];
        if (!f) return;
        const url = await readDataUrl(f);
        this.change(k, "Effect video", (c) => { c.effect.video = url; });
      });
      row(e.video ? "video (loaded)" : "video", file);
      vec("centre (m)", e.center_m, (v, c) => { c.effect.center_m = v; });
      num("width (m)", e.width_m, (v, c) => { c.effect.width_m = v; }, { min: "0", max: "100000", exclusive: "min" });
      num("height (m)", e.height_m, (v, c) => { c.effect.height_m = v; }, { min: "0", max: "100000", exclusive: "min" });
      this._cameraField(k, e);
    }
  }

  /** The audience camera of an image / video effect: "x, y, z", blank for the straight front view.
   * @param {number} k @param {any} e */
  _cameraField(k, e) {
    const input = document.createElement("input");
    input.type = "text";
    input.placeholder = "front view (x, y, z: camera)";
    input.value = e.camera_m ? e.camera_m.join(", ") : "";
    input.setAttribute("aria-label", "Effect audience camera (m)");
    input.addEventListener("change", () => {
      const text = input.value.trim();
      const v = text ? parseNumbers(text) : null;
      if (text && !v) { this.hooks.toast?.("camera: three numbers, x, y, z, or blank", { error: true }); return; }
      this.change(k, "Effect camera", (c) => {
        if (v) c.effect.camera_m = v;
        else delete c.effect.camera_m;
      });
    });
    const div = document.createElement("div");
    div.className = "row";
    const l = document.createElement("label");
    l.textContent = "camera (m)";
    div.append(l, input);
    this.$form.append(div);
  }
}
