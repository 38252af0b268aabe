// @ts-check
// The music lane under the timeline (issue 18): the show's audio track (upload, play, seek), its
// waveform peaks and beats from the server, the formations' cue markers (drag to pin a formation's
// arrival, snapping to beats; double-click to unpin) and the playhead. With the 3D preview open,
// the sound follows the viewer's clock and the lane's transport drives the viewer.

import * as api from "./api.js";
import { setError } from "./errors.js";
import { fitCanvas } from "./hidpi.js";
import { columnPeaks, snapTime } from "./musicmath.js";

/** Snap distance to a beat, CSS pixels. */
const SNAP_PX = 10;
/** Height of the departure markers' handles along the lane's bottom, CSS pixels. */
const LEAVE_HANDLE_PX = 14;
/** Grab distance of a marker, CSS pixels. */
const GRAB_PX = 7;
/** Audio and viewer clocks further apart than this are re-aligned, seconds. */
const DRIFT_S = 0.15;
/** After the lane drives the viewer, its clock is not followed for this long, milliseconds. */
const QUIET_MS = 1500;
/** How often the viewer's clock is read while the preview is open, milliseconds. */
const CLOCK_POLL_MS = 500;
/** Wait on a music upload after which its status says why the first analysis is slow, milliseconds. */
export const SLOW_ANALYSIS_MS = 8000;
/** Why the first analysis on a server takes minutes (the status after SLOW_ANALYSIS_MS). */
export const FIRST_ANALYSIS_NOTE = "The first analysis on a server compiles the beat tracker (1-2 min); later uploads take seconds.";

/** The music lane. */
export class MusicLane {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {{plan: () => any, previewOpen: () => boolean, pinned?: (k: number) => void}} parts the last fresh
   *   check's plan summary, whether the 3D preview is open, and what to do once a cue time is pinned (the check
   *   that says at once whether the transition can make it)
   */
  constructor(state, parts) {
    this.state = state;
    this.parts = parts;
    this.canvas = /** @type {HTMLCanvasElement} */ (document.getElementById("music-canvas"));
    this.audio = /** @type {HTMLAudioElement} */ (document.getElementById("music-audio"));
    this.file = /** @type {HTMLInputElement} */ (document.getElementById("music-file"));
    this.playBtn = /** @type {HTMLButtonElement} */ (document.getElementById("btn-music-play"));
    this.timeEl = document.getElementById("music-time");
    this.snapBox = /** @type {HTMLSelectElement} */ (document.getElementById("music-snap"));
    /** @type {any|null} the analysis: duration_s, peaks_per_s, peaks, tempo_bpm, beats_s, onsets_s */
    this.analysis = null;
    /** @type {any|null} what the server says of the stored track */
    this.info = null;
    /** Playhead, seconds of show time (the audio's time when there is audio). */
    this.time_s = 0;
    this.playing = false;
    this._clockStart = 0;
    this._drag = null;
    this._raf = 0;
    this._poll = 0;
    this._followed = false;
    this._quietUntil = 0;
    /** Names this lane's transport requests to the server, which ignores one overtaken by a later one. */
    this._sender = `lane-${Math.random().toString(36).slice(2)}-${Date.now().toString(36)}`;
    this._seq = 0;

    this.file.addEventListener("change", () => {
      const f = this.file.files && this.file.files[0];
      if (f) this.upload(f);
      this.file.value = "";
    });
    document.getElementById("btn-music-remove").addEventListener("click", () => this.remove());
    this.playBtn.addEventListener("click", () => this.toggle());
    document.getElementById("btn-music-pin").addEventListener("click", () => this.pinCurrent(this.time_s, "arrive"));
    document.getElementById("btn-music-pin-leave").addEventListener("click", () => this.pinCurrent(this.time_s, "leave"));
    document.getElementById("btn-music-unpin").addEventListener("click", () => this.unpin(this.state.current));
    this.canvas.addEventListener("pointerdown", (e) => this._down(e));
    this.canvas.addEventListener("pointermove", (e) => this._move(e));
    this.canvas.addEventListener("pointerup", (e) => this._up(e));
    this.canvas.addEventListener("dblclick", (e) => this._dbl(e));
    this.audio.addEventListener("ended", () => this.pause(false));
    state.addEventListener("change", (/** @type {CustomEvent} */ e) => {
      if (e.detail.kind === "load") this.reload();
      else this.draw();
    });
    new ResizeObserver(() => this.draw()).observe(this.canvas);
    this._poll = window.setInterval(() => this._follow(), CLOCK_POLL_MS);
  }

  // ---- track ---------------------------------------------------------------------------------

  /**
   * The stored track of the open show (none: an empty lane).
   * @param {boolean} [hasAudio] whether the show has music now (default: what its record said when it was
   *   opened); without music nothing is asked (the track's info would be a 404, logged by the browser)
   */
  async reload(hasAudio = undefined) {
    this.pause(false);
    this.analysis = this.info = null;
    this.audio.removeAttribute("src");
    this.audio.load();
    this.time_s = 0;
    setError("music", "");
    const meta = this.state.meta;
    if (meta) meta.has_audio = hasAudio ?? meta.has_audio !== false;
    if (meta && meta.has_audio) {
      try {
        this.info = await api.request("GET", `/api/shows/${meta.id}/audio/info`);
        this.analysis = await api.request("GET", `/api/shows/${meta.id}/audio/analysis`);
        this.audio.src = `/api/shows/${meta.id}/audio?v=${this.info.sha256.slice(0, 12)}`;
      } catch (err) {
        if (!(err instanceof api.ApiError && err.status === 404)) setError("music", `Cannot load the music: ${err.message}`);
      }
    }
    this._chrome();
    this.draw();
  }

  /**
   * Upload a file as the show's music (decoded, checked and analysed on the server).
   * @param {File} file
   */
  async upload(file) {
    const meta = this.state.meta;
    if (!meta) return;
    setError("music", "");
    this.canvas.setAttribute("aria-busy", "true");
    const status = document.getElementById("music-status");
    if (status) status.textContent = `Analysing ${file.name}…`;
    // The first analysis on a server compiles librosa's beat tracker (numba, cached per machine afterwards):
    // about two minutes of "Analysing…" with no word why looks like a hang, so say it after a short wait.
    const slow = window.setTimeout(() => {
      if (status) status.textContent = `Analysing ${file.name}… ${FIRST_ANALYSIS_NOTE}`;
    }, SLOW_ANALYSIS_MS);
    try {
      await api.request("PUT", `/api/shows/${meta.id}/audio?filename=${encodeURIComponent(file.name)}`, {
        body: file, headers: { "Content-Type": file.type || "application/octet-stream" },
      });
      await this.reload(true);
    } catch (err) {
      setError("music", `Music not loaded: ${err.message}`);
    } finally {
      clearTimeout(slow);
      this.canvas.removeAttribute("aria-busy");
      if (status) status.textContent = "";
      this._chrome();
    }
  }

  /** Remove the show's music. */
  async remove() {
    const meta = this.state.meta;
    if (!meta || !this.info) return;
    let gone = true;
    try {
      await api.request("DELETE", `/api/shows/${meta.id}/audio`);
    } catch (err) {
      if (!(err instanceof api.ApiError && err.status === 404)) {  // 404: removed already (another tab)
        gone = false;
        setError("music", `Cannot remove the music: ${err.message}`);
      }
    }
    await this.reload(gone ? false : undefined);
  }

  _chrome() {
    const status = document.getElementById("music-status");
    const has = !!this.info;
    /** @type {HTMLButtonElement} */ (document.getElementById("btn-music-remove")).disabled = !has;
    if (status && !this.canvas.hasAttribute("aria-busy")) {
      status.textContent = has
        ? `${this.info.filename} · ${this.info.duration_s.toFixed(1)} s${this.info.tempo_bpm ? ` · ${this.info.tempo_bpm.toFixed(1)} BPM` : ""}`
        : "No music";
    }
    this.canvas.setAttribute("aria-label", has
      ? `Music lane: ${this.info.filename}, ${this.analysis ? this.analysis.beats_s.length : 0} beats; drag a formation marker to pin its arrival`
      : "Music lane: no music; drag a formation marker to pin its arrival");
  }

  // ---- transport -----------------------------------------------------------------------------

  /** @returns {number} the lane's time span, seconds. */
  span() {
    const plan = this.parts.plan();
    const pins = (this.state.show ? this.state.show.formations : []).flatMap((f) => [f.arrive_at_s || 0, f.leave_at_s || 0]);
    return Math.max(10, plan ? plan.duration_s : 0, this.analysis ? this.analysis.duration_s : 0, ...pins.map((t) => t + 5));
  }

  /** Play or pause. */
  toggle() {
    if (this.playing) this.pause();
    else this.play();
  }

  /**
   * Start the playhead (and the sound, and the 3D view when it is open).
   * @param {boolean} [drive] also start the viewer
   */
  async play(drive = true) {
    if (this.playing) return;
    this.playing = true;
    this._clockStart = performance.now() / 1000 - this.time_s;
    const sound = this.info && this.time_s < this.analysis.duration_s;
    if (sound) this.audio.currentTime = this.time_s;
    // The playhead and the viewer start now, not when the sound's play() settles: on a busy machine that
    // promise can stay pending for many seconds while the sound already plays (the playhead then sat still
    // and the 3D view paused). Until the sound is audible the playhead runs on the wall clock (see _tick).
    this.playBtn.textContent = "❚❚ Pause";
    this.playBtn.setAttribute("aria-pressed", "true");
    if (drive) this._transport({ time_s: this.time_s, playing: true });
    this._tick();
    if (sound) {
      try {
        await this.audio.play();
      } catch (err) {
        // A pause before the sound started interrupts play() (AbortError): no failure.
        if (!(err && err.name === "AbortError")) {
          setError("music", `The browser did not start the sound (${err.message}); press Play again.`);
        }
      }
    }
  }

  /**
   * Stop the playhead.
   * @param {boolean} [drive] also pause the viewer
   */
  pause(drive = true) {
    const was = this.playing;
    this.playing = false;
    this.audio.pause();
    cancelAnimationFrame(this._raf);
    this.playBtn.textContent = "▶ Play";
    this.playBtn.setAttribute("aria-pressed", "false");
    if (drive && was) this._transport({ playing: false, time_s: this.time_s });
    this.draw();
  }

  /**
   * Move the playhead.
   * @param {number} t seconds
   * @param {boolean} [drive] also seek the viewer
   */
  seek(t, drive = true) {
    this.time_s = Math.max(0, t);
    this._clockStart = performance.now() / 1000 - this.time_s;
    if (this.info) this.audio.currentTime = Math.min(this.time_s, this.analysis.duration_s);
    if (drive) this._transport({ time_s: this.time_s });
    this.draw();
    this.state.dispatchEvent(new CustomEvent("playhead", { detail: { time_s: this.time_s } }));
  }

  _tick() {
    if (!this.playing) return;
    // The sound is the clock while it plays (the browser keeps it steady); else the wall clock.
    const audible = this.info && !this.audio.paused && !this.audio.ended;
    this.time_s = audible ? this.audio.currentTime : performance.now() / 1000 - this._clockStart;
    if (audible) this._clockStart = performance.now() / 1000 - this.time_s;
    this.draw();
    this.state.dispatchEvent(new CustomEvent("playhead", { detail: { time_s: this.time_s } }));
    this._raf = requestAnimationFrame(() => this._tick());
  }

  /** @param {{time_s?: number, playing?: boolean}} body */
  _transport(body) {
    if (!this.parts.previewOpen() || !this.state.meta) return;
    // Until the viewer has applied it, its clock still says the old state: do not follow that back.
    this._quietUntil = performance.now() + QUIET_MS;
    // Sent at once (a request queued behind another waits for this page's main thread, which a busy 3D view
    // can hold for many seconds); numbered, so that the server ignores one that arrives after a later one
    // (a quick Play then Pause, each on its own connection, could leave the viewer playing).
    const json = { show_id: this.state.meta.id, ...body, sender: this._sender, seq: ++this._seq };
    api.request("POST", "/api/viewer/transport", { json }).catch(() => {});
  }

  /** Follow the 3D view's clock: its play / pause, its time (beyond the drift) and its speed. */
  async _follow() {
    if (!this.parts.previewOpen() || !this.state.meta || document.hidden) return;
    if (performance.now() < this._quietUntil) return;
    let c;
    try {
      c = await api.request("GET", `/api/viewer/clock?show_id=${encodeURIComponent(this.state.meta.id)}`);
    } catch {
      return;
    }
    if (!c.show || performance.now() < this._quietUntil) return;
    this.audio.playbackRate = Math.min(4, Math.max(0.25, c.speed));
    if (c.playing && !this.playing) {
      this.time_s = c.time_s;
      this._followed = true;
      await this.play(false);
    } else if (!c.playing && this.playing && this._followed) {
      this._followed = false;
      this.pause(false);
      this.seek(c.time_s, false);
    } else if (Math.abs(c.time_s - this.time_s) > DRIFT_S * Math.max(1, c.speed)) {
      this.seek(c.time_s, false);
    }
  }

  // ---- cues ----------------------------------------------------------------------------------

  /** @returns {number[]} the snap points (beats, onsets or both, as chosen), seconds, ascending. */
  snapPoints() {
    const a = this.analysis;
    const mode = this.snapBox.value;
    if (!a || mode === "off") return [];
    if (mode === "onsets") return a.onsets_s;
    if (mode === "both") return [...a.beats_s, ...a.onsets_s].sort((x, y) => x - y);
    return a.beats_s;
  }

  /**
   * Each formation's cue markers: its arrival and its departure, pinned or (after a check) planned.
   * @returns {{k: number, kind: "arrive"|"leave", t: number, pinned: boolean}[]}
   */
  markers() {
    const show = this.state.show;
    if (!show) return [];
    const plan = this.parts.plan();
    const holds = plan ? plan.segments.filter((s) => s.kind === "hold") : [];
    const out = [];
    show.formations.forEach((f, k) => {
      const hold = holds[k] || null;
      const arrive = f.arrive_at_s != null ? f.arrive_at_s : hold ? hold.start_s : null;
      const leave = f.leave_at_s != null ? f.leave_at_s : hold ? hold.start_s + hold.duration_s : null;
      if (arrive != null) out.push({ k, kind: "arrive", t: arrive, pinned: f.arrive_at_s != null });
      if (leave != null) out.push({ k, kind: "leave", t: leave, pinned: f.leave_at_s != null });
    });
    return out;
  }

  /**
   * Pin the current formation's arrival (or departure) at `t`, snapped to the nearest snap point.
   * @param {number} t seconds @param {"arrive"|"leave"} [kind]
   */
  pinCurrent(t, kind = "arrive") {
    this.pin(this.state.current, kind, +snapTime(t, this.snapPoints(), 0.25).toFixed(3));
  }

  /**
   * Pin formation `k` to arrive (or leave) at `t` seconds. A fixed transition length gives way to an
   * arrival pin; a departure pin before the arrival pin is dropped.
   * @param {number} k @param {"arrive"|"leave"} kind @param {number} t
   */
  pin(k, kind, t) {
    const st = this.state;
    if (!st.show || !st.show.formations[k]) return;
    t = Math.max(0, t);
    const verb = kind === "arrive" ? "arrival" : "departure";
    st.edit(`Pin the ${verb} of "${st.show.formations[k].name}" at ${t.toFixed(2)} s`, () => {
      const f = st.show.formations[k];
      if (kind === "arrive") {
        f.arrive_at_s = t;
        delete f.transition_s;
        if (f.leave_at_s != null && f.leave_at_s <= t) delete f.leave_at_s;
      } else {
        f.leave_at_s = t;
        if (f.arrive_at_s != null && f.arrive_at_s >= t) delete f.arrive_at_s;
      }
    });
    // A pin the transition cannot make (shorter than the limits allow) is refused by the plan: the designer
    // learns it now, on the formation's card, rather than at Simulate.
    if (this.parts.pinned) this.parts.pinned(k);
  }

  /**
   * Unpin formation `k`'s arrival, departure or both: they follow the plan (and hold_s) again.
   * @param {number} k @param {"arrive"|"leave"|"both"} [kind]
   */
  unpin(k, kind = "both") {
    const st = this.state;
    const f = st.show && st.show.formations[k];
    if (!f) return;
    const fields = kind === "both" ? ["arrive_at_s", "leave_at_s"] : [`${kind}_at_s`];
    if (!fields.some((x) => f[x] != null)) return;
    st.edit(`Unpin "${f.name}"`, () => {
      for (const x of fields) delete st.show.formations[k][x];
    });
    if (this.parts.pinned) this.parts.pinned(k);
  }

  _x(t) {
    return (t / this.span()) * this.canvas.clientWidth;
  }

  _t(x) {
    return (x / Math.max(1, this.canvas.clientWidth)) * this.span();
  }

  /** The marker under (x, y): departures by their handle along the bottom, arrivals elsewhere. */
  _hit(x, y) {
    const kind = y >= this.canvas.clientHeight - LEAVE_HANDLE_PX ? "leave" : "arrive";
    let best = null;
    let bestD = GRAB_PX;
    for (const m of this.markers()) {
      const d = Math.abs(this._x(m.t) - x);
      if (m.kind === kind && d <= bestD) {
        bestD = d;
        best = m;
      }
    }
    return best;
  }

  /** @param {PointerEvent} e */
  _down(e) {
    const m = this._hit(e.offsetX, e.offsetY);
    if (m) {
      this._drag = { k: m.k, kind: m.kind, t: m.t };
      this.state.setCurrent(m.k);
    } else {
      this._drag = { seek: true };
      this.seek(this._t(e.offsetX));
    }
    this.canvas.setPointerCapture(e.pointerId);
  }

  /** @param {PointerEvent} e */
  _move(e) {
    const d = this._drag;
    if (!d) {
      this.canvas.style.cursor = this._hit(e.offsetX, e.offsetY) ? "ew-resize" : "pointer";
      return;
    }
    const t = Math.max(0, this._t(e.offsetX));
    if (d.seek) this.seek(t);
    else {
      d.moved = true;
      const radius = e.shiftKey ? 0 : this._t(SNAP_PX);
      d.t = snapTime(t, this.snapPoints(), radius);
      this.draw();
    }
  }

  /** @param {PointerEvent} e */
  _up(e) {
    const d = this._drag;
    this._drag = null;
    if (this.canvas.hasPointerCapture(e.pointerId)) this.canvas.releasePointerCapture(e.pointerId);
    if (d && !d.seek && d.moved) this.pin(d.k, d.kind, +d.t.toFixed(3));
    else this.draw();
  }

  /** @param {MouseEvent} e */
  _dbl(e) {
    const m = this._hit(e.offsetX, e.offsetY);
    if (m && m.pinned) this.unpin(m.k, m.kind);
  }

  // ---- drawing -------------------------------------------------------------------------------

  /** Redraw the lane: waveform, beats, markers, playhead. */
  draw() {
    const fit = fitCanvas(this.canvas);
    if (!fit) return;
    const { g, w, h } = fit;
    const span = this.span();
    const mid = h / 2 + 6;
    const amp = h / 2 - 10;
    // Seconds ruler.
    g.fillStyle = "#8a94a6";
    g.font = "10px sans-serif";
    const step = [1, 2, 5, 10, 15, 30, 60, 120, 300].find((s) => (s / span) * w >= 40) || 600;
    for (let t = 0; t <= span; t += step) {
      const x = this._x(t);
      g.fillRect(x, 0, 1, 4);
      g.fillText(`${t}s`, x + 2, 10);
    }
    // Waveform.
    const a = this.analysis;
    if (a) {
      const cols = columnPeaks(a.peaks, a.peaks_per_s, 0, span, Math.floor(w));
      g.fillStyle = "#3d6fa8";
      for (let x = 0; x < cols.length / 2; x++) {
        const lo = cols[2 * x];
        const hi = cols[2 * x + 1];
        if (hi > lo) g.fillRect(x, mid - hi * amp, 1, Math.max(1, (hi - lo) * amp));
      }
      // Beats (thinned when closer than 3 px).
      g.fillStyle = "rgba(255, 214, 102, 0.55)";
      let last = -10;
      for (const b of a.beats_s) {
        const x = this._x(b);
        if (x - last < 3) continue;
        last = x;
        g.fillRect(x, 12, 1, h - 12);
      }
    }
    // Formation markers: arrivals (diamonds from the top), departures (handles along the bottom).
    const show = this.state.show;
    for (const m of this.markers()) {
      const dragging = this._drag && this._drag.k === m.k && this._drag.kind === m.kind;
      const x = this._x(dragging ? this._drag.t : m.t);
      const current = show && m.k === this.state.current;
      const solid = m.pinned || dragging;
      g.strokeStyle = g.fillStyle = solid ? (current ? "#ff9f43" : "#e0e0e0") : "#7f8ea3";
      g.lineWidth = current ? 2 : 1;
      g.beginPath();
      if (m.kind === "arrive") {
        g.moveTo(x, 12);
        g.lineTo(x, h - LEAVE_HANDLE_PX);
        g.stroke();
        g.beginPath();
        g.moveTo(x, 12);
        g.lineTo(x - 5, 18);
        g.lineTo(x, 24);
        g.lineTo(x + 5, 18);
        g.closePath();
        if (solid) g.fill();
        else g.stroke();
        g.fillText(show.formations[m.k].name.slice(0, 16), x + 6, 22);
      } else {
        g.moveTo(x, h - 2 * LEAVE_HANDLE_PX);
        g.lineTo(x, h);
        g.stroke();
        g.beginPath();
        g.rect(x - 4, h - LEAVE_HANDLE_PX + 2, 4, LEAVE_HANDLE_PX - 4);
        if (solid) g.fill();
        else g.stroke();
      }
    }
    // Playhead.
    g.fillStyle = "#ff4757";
    g.fillRect(this._x(this.time_s) - 1, 0, 2, h);
    if (this.timeEl) this.timeEl.textContent = `${this.time_s.toFixed(2)} s`;
  }
}
