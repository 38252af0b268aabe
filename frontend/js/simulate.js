// @ts-check
// "Simulate": start the flight simulation job, follow its progress (server-sent events, or
// polling when events are unavailable), show the tracking and flown-separation summary.

import * as api from "./api.js";
import { setError, showShowErrors } from "./errors.js";
import { flightRequest, flightRows, randomSeed, REASONS, seedProblem } from "./flight.js";
import { fmt, summaryTable } from "./summary.js";

/** "2 overpowered, 1 runaway" from a `{reason: count}` map. @param {Record<string, number>|undefined} byReason */
function reasonList(byReason) {
  return Object.entries(byReason || {}).map(([k, n]) => `${n} ${k}`).join(", ") || "—";
}

export class SimulatePanel {
  /**
   * @param {import("./state.js").EditorState} state
   * @param {import("./persist.js").Persistence} persist
   * @param {{onSelectDrones?: (drones: number[]) => void, onFlown?: () => void,
   *   onPlayRun?: (run: {job_id: string, run?: number}, startTime?: number|null) => Promise<void>,
   *   onFormationProblems?: () => void, onPlanned?: (plan: any) => void}} [hooks] onFormationProblems: a failure
   *   named formations (marked); onPlanned: a simulation finished with its plan (the server's plan summary)
   *   onFlown: a simulation finished; onPlayRun: play a Monte-Carlo run, or a simulation job's flight (no `run`),
   *   in the 3D preview, from `startTime` (its closest pair)
   */
  constructor(state, persist, hooks = {}) {
    this.state = state;
    this.persist = persist;
    this.hooks = hooks;
    this.job = null;
    this.source = null;
    this.pollTimer = 0;
    /** @type {number|null} document version of the last finished simulation */
    this.flownVersion = null;
    this.startedVersion = null;
    this.bar = /** @type {HTMLProgressElement} */ (document.getElementById("sim-progress"));
    this.percent = document.getElementById("sim-percent");
    this.body = document.getElementById("sim-body");
    this.cancelBtn = document.getElementById("btn-sim-cancel");
    this.cancelBtn.addEventListener("click", () => this.cancel());
    this.preset = /** @type {HTMLSelectElement} */ (document.getElementById("sim-preset"));
    this.seed = /** @type {HTMLInputElement} */ (document.getElementById("sim-seed"));
    this.disturbance = /** @type {HTMLSelectElement} */ (document.getElementById("sim-disturbance"));
    /** @type {string|null} the simulation job whose flight the 3D preview plays (its preset and seed) */
    this.flightJob = null;
    // The designer's last preset and seed come back with the page (the same seed flies the same flight).
    const savedPreset = localStorage.getItem("swarmshow.sim.preset");
    if (savedPreset && [...this.preset.options].some((o) => o.value === savedPreset)) this.preset.value = savedPreset;
    const savedSeed = localStorage.getItem("swarmshow.sim.seed");
    if (savedSeed !== null && !seedProblem(savedSeed)) this.seed.value = savedSeed;
    this.preset.addEventListener("change", () => localStorage.setItem("swarmshow.sim.preset", this.preset.value));
    const keepSeed = () => { if (!seedProblem(this.seed.value)) localStorage.setItem("swarmshow.sim.seed", this.seed.value.trim()); };
    this.seed.addEventListener("change", keepSeed);
    document.getElementById("btn-sim-seed").addEventListener("click", () => {
      this.seed.value = String(randomSeed());
      setError("sim-seed", "");
      keepSeed();
    });
    this.seed.addEventListener("input", () => setError("sim-seed", ""));
    // A fleet-wide disturbance is for the ideal vehicle; every other preset brings its own wind field.
    const ideal = () => { this.disturbance.disabled = this.preset.value !== "ideal"; };
    this.preset.addEventListener("change", ideal);
    ideal();
    state.addEventListener("change", (/** @type {any} */ e) => {
      if (e.detail.kind === "load") this.reset();
    });
  }

  /** @returns {boolean} a simulation of the document as it is now has finished (the 3D view can play it). */
  get hasFlight() {
    return this.flownVersion != null && this.flownVersion === this.state.version;
  }

  /** @returns {{job_id: string}|undefined} the finished simulation the 3D preview plays (its preset and seed). */
  get flight() {
    return this.hasFlight && this.flightJob ? { job_id: this.flightJob } : undefined;
  }

  /** Stop following the job and clear the panel. */
  reset() {
    this._stopFollowing();
    this.job = null;
    this._progress(0, "—");
    this.cancelBtn.hidden = true;
    this.body.innerHTML = '<p class="muted">Simulate flies every drone through the quadrotor model with ISMC control.</p>';
  }

  _progress(fraction, text) {
    this.bar.value = fraction;
    this.percent.textContent = text ?? `${Math.round(fraction * 100)}%`;
  }

  _message(cls, text) {
    this.body.replaceChildren();
    const p = document.createElement("p");
    p.className = cls;
    p.textContent = text;
    this.body.append(p);
  }

  /** Save if needed, then start a simulation and follow it. */
  async run() {
    const st = this.state;
    if (!st.meta) return;
    this._stopFollowing();
    const seedText = this.seed.value;
    const bad = seedProblem(seedText);
    setError("sim-seed", bad);
    if (bad) {
      this.seed.focus();
      return;
    }
    const btn = /** @type {HTMLButtonElement} */ (document.getElementById("btn-simulate"));
    btn.disabled = true;
    try {
      if (!(await this.persist.ensureSaved())) {
        this._message("report-bad", "Not simulated: the show could not be saved.");
        return;
      }
      const draft = this.persist.draftRefusal("simulated");
      if (draft) {
        this._message("report-bad", draft);
        return;
      }
      this._progress(0, "0%");
      this._message("muted", "Starting…");
      const controller = /** @type {HTMLSelectElement} */ (document.getElementById("sim-controller")).value;
      const runsSel = /** @type {HTMLSelectElement|null} */ (document.getElementById("sim-runs"));
      const runs = runsSel ? Number(runsSel.value) || 1 : 1;
      this.startedVersion = st.version;
      // One flight under the error preset with the seed, or a Monte-Carlo of K runs from that seed (its run 0
      // is the flight of the same seed): the safety margin and report.
      const req = flightRequest({ runs, preset: this.preset.value, seed: Number(seedText), controller,
        disturbance: this.disturbance.value });
      const job = req.kind === "montecarlo" ? await api.monteCarloShow(st.meta.id, req.options)
        : await api.simulateShow(st.meta.id, req.options);
      this.job = job;
      this._update(job);
      if (!["done", "failed", "cancelled"].includes(job.state)) this._follow(job.id);
    } catch (err) {
      this._message("report-bad", `Not simulated: ${err.message}`);
      this._progress(0, "—");
    } finally {
      btn.disabled = !st.meta;
    }
  }

  _follow(id) {
    this.cancelBtn.hidden = false;
    if (sessionStorage.getItem("swarmshow.token") || typeof EventSource === "undefined") {
      this._poll(id);
      return;
    }
    const es = new EventSource(api.jobEventsUrl(id));
    this.source = es;
    es.addEventListener("progress", (e) => this._update(JSON.parse(e.data)));
    for (const kind of ["done", "failed", "cancelled"]) {
      es.addEventListener(kind, (e) => {
        es.close();
        this.source = null;
        this._update(JSON.parse(e.data));
      });
    }
    es.onerror = () => {
      // The stream broke before a final event: fall back to polling the job.
      if (this.source !== es) return;
      es.close();
      this.source = null;
      this._poll(id);
    };
  }

  _poll(id) {
    const tick = async () => {
      try {
        const job = await api.getJob(id);
        this._update(job);
        if (!["done", "failed", "cancelled"].includes(job.state)) this.pollTimer = setTimeout(tick, 700);
      } catch (err) {
        this._message("report-bad", `Lost track of the simulation: ${err.message}`);
      }
    };
    tick();
  }

  _stopFollowing() {
    if (this.source) this.source.close();
    this.source = null;
    clearTimeout(this.pollTimer);
  }

  async cancel() {
    if (!this.job) return;
    this._stopFollowing();
    try {
      const job = await api.cancelJob(this.job.id);
      this._update(job);
    } catch (err) {
      this._message("report-bad", `Cannot cancel: ${err.message}`);
    }
  }

  _update(job) {
    this.job = { ...this.job, ...job };
    const p = Number(job.progress) || 0;
    if (job.state === "queued") this._progress(p, "queued");
    else if (job.state === "running") {
      this._progress(p);
      // A note says what holds the progress up (the server compiling the flight kernel on a cold cache).
      const note = job.note ? ` (${job.note})` : "";
      this._message("muted",
        `${this.job.kind === "montecarlo" ? "Flying the runs" : "Flying"}… ${Math.round(p * 100)}%${note}`);
    } else if (job.state === "done" && this.job.kind === "montecarlo") {
      this._progress(1, "100%");
      this.cancelBtn.hidden = true;
      this._monteCarlo(this.job.id, (job.result || {}).montecarlo || {}, job.cached);
    } else if (job.state === "done") {
      const fresh = this.flownVersion !== this.startedVersion || this.flightJob !== this.job.id;
      this.flownVersion = this.startedVersion;
      this.flightJob = this.job.id;
      if (fresh && this.hooks.onFlown) this.hooks.onFlown();
      this._progress(1, "100%");
      this.cancelBtn.hidden = true;
      this._summary(job.result || {}, job.cached, this.job.id);
      if (this.hooks.onPlanned) this.hooks.onPlanned((job.result || {}).plan);
      // The answer the designer waited for, on screen (the panel sits below the fold on a laptop).
      this.body.scrollIntoView({ block: "nearest" });
    } else if (job.state === "failed" || job.state === "cancelled") {
      this.cancelBtn.hidden = true;
      this._progress(p, job.state);
      const detail = job.error && Array.isArray(job.error.detail) ? job.error.detail : [];
      const why = job.error ? job.error.message || detail.map((d) => (d.path ? `${d.path}: ${d.msg}` : d.msg)).join("; ")
        || JSON.stringify(job.error.detail) : "";
      this._message("report-bad", job.state === "cancelled" ? "Cancelled." : `Failed: ${why}`);
      // As the check and the exports: a formation the refusal names is marked on its timeline card.
      const named = detail.filter((d) => /^formations\[\d+\]/.test((d && d.path) || ""));
      if (named.length) {
        showShowErrors(named, () => {});
        if (this.hooks.onFormationProblems) this.hooks.onFormationProblems();
      }
    }
  }

  /**
   * The Monte-Carlo summary: flown separation over the runs, probabilities, extra spacing, and links
   * to the safety report (HTML, PDF) and to the worst run in the 3D view.
   * @param {string} jobId @param {any} mc the job's `result.montecarlo` @param {boolean} cached
   */
  _monteCarlo(jobId, mc, cached) {
    this.body.replaceChildren();
    const s = mc.show_min || {};
    const below = s.p_below_min_distance || {};
    const coll = s.p_collision || {};
    const ok = below.runs_below === 0 && !mc.diverged_count;
    const q = (s.flown_min_m || {}).quantiles || {};
    const pct = (p) => p.p == null ? "—"
      : `${(100 * p.p).toFixed(1)} % (${(100 * p.ci_low).toFixed(1)}–${(100 * p.ci_high).toFixed(1)} %)`;
    this.body.append(...summaryTable(ok, ok ? `✓ ${mc.runs} runs: every run kept the minimum distance`
      : `✗ ${below.runs_below} of ${mc.runs} runs came closer than ${fmt(mc.min_distance_m, 1, " m")}`,
    "Monte-Carlo summary", [
      ["Flown min separation", `worst ${fmt(q["0"], 2, " m")}, median ${fmt(q["0.5"], 2, " m")}`, !ok],
      [`P(closer than ${fmt(mc.min_distance_m, 1, " m")})`, pct(below), below.runs_below > 0],
      [`P(collision, < ${fmt(mc.collision_distance_m, 1, " m")})`, pct(coll), coll.runs_below > 0],
      [`Extra spacing at ${Math.round(1000 * (mc.confidence || 0)) / 10} %`, fmt((s.extra_spacing || {}).extra_m, 2, " m")],
      ["Largest deviation", fmt((mc.deviation || {}).max_m, 3, " m")],
      mc.diverged_count > 0 && ["Diverged", `${mc.diverged_count} drone-runs (${reasonList(mc.diverged_by_reason)})`, true],
      ["Preset", `${mc.preset || "—"}, ${mc.controller || ""}, seeds ${mc.seed0}–${mc.seed0 + mc.runs - 1}`],
      mc.wall_time_s != null && ["Computed in", `${fmt(mc.wall_time_s, 1, " s")}${cached ? " (cached)" : ""}`],
    ]));
    const links = document.createElement("p");
    const report = document.createElement("a");
    report.id = "sim-report-link";
    report.href = api.safetyReportUrl(jobId, "html");
    report.target = "_blank";
    report.rel = "noopener";
    report.textContent = "Safety report";
    const pdf = document.createElement("a");
    pdf.href = api.safetyReportUrl(jobId, "pdf");
    pdf.textContent = "PDF";
    pdf.setAttribute("download", "");
    links.append(report, " · ", pdf);
    const worst = s.worst_run;
    if (worst && this.state.meta) {
      const showId = this.state.meta.id;
      const play = document.createElement("button");
      play.type = "button";
      play.id = "sim-play-worst";
      play.textContent = `Play worst run (seed ${worst.seed}) in 3D`;
      play.addEventListener("click", async () => {
        const run = { job_id: jobId, run: worst.run };
        // In the editor the run plays in the 3D preview, opened for it (loading it into the viewer
        // alone changed nothing on screen while the preview was closed), at its closest pair.
        if (this.hooks.onPlayRun) return this.hooks.onPlayRun(run, worst.time_s);
        try {
          await api.loadPlayback(showId, "simulated", run);
        } catch (err) {
          this._message("report-bad", `Cannot play the run: ${err.message}`);
        }
      });
      links.append(" · ", play);
      // That run is the single flight of its seed: fly it alone for its full summary.
      const alone = document.createElement("button");
      alone.type = "button";
      alone.id = "sim-fly-worst";
      alone.textContent = `Fly seed ${worst.seed} alone`;
      alone.addEventListener("click", () => {
        const runsSel = /** @type {HTMLSelectElement|null} */ (document.getElementById("sim-runs"));
        if (runsSel) runsSel.value = "1";
        if (mc.preset) this.preset.value = mc.preset;
        this.preset.dispatchEvent(new Event("change"));
        this.seed.value = String(worst.seed);
        this.seed.dispatchEvent(new Event("change"));
        this.run();
      });
      links.append(" · ", alone);
    }
    this.body.append(links);
  }

  /**
   * The flight summary: preset and seed, deviation from the plan, flown separation against the limit, the
   * closest pair, the drones that diverged and why, and the flight in 3D beside the plan.
   * @param {any} result the job's result @param {boolean} cached @param {string} [jobId] the simulation job
   */
  _summary(result, cached, jobId) {
    const f = result.flight || result;
    /** @type {{path: string, msg: string}[]} transitions forced shorter than the limits allow, flown as designed */
    const problems = Array.isArray(result.problems) ? result.problems : [];
    this.body.replaceChildren();
    const ok = f.ok !== false && !problems.length;
    const headline = ok ? "✓ Flown: separation kept, no divergence"
      : problems.length ? "✗ Flown as designed, but the design breaks the limits" : "✗ The flown show breaks a limit";
    this.body.append(...summaryTable(ok, headline, "Flight summary", flightRows(f, cached)));
    for (const pr of problems) {
      const p = document.createElement("p");
      p.className = "report-bad sim-problem";
      p.textContent = `${pr.msg} (exports refuse the show until this is fixed)`;
      this.body.append(p);
    }
    if (Array.isArray(f.diverged) && f.diverged.length) {
      const p = document.createElement("p");
      p.className = "report-bad";
      p.textContent = `Diverged: ${f.diverged.slice(0, 10).map((d) => `drone ${d.drone} at ${fmt(d.time_s, 1)} s (${d.reason})`).join("; ")}`;
      p.title = Object.values(REASONS).join("\n");
      // What each reason that occurred means, on screen (a tooltip alone is easily missed).
      const why = document.createElement("p");
      why.className = "muted sim-reasons";
      why.textContent = [...new Set(f.diverged.map((d) => d.reason))]
        .map((r) => (Object.hasOwn(REASONS, r) ? REASONS[r] : r)).join(". ");
      this.body.append(p, why);
    }
    if (jobId && this.state && this.state.meta) {
      // The flown trajectories beside the plan, each drone's gap coloured (the viewer's simulated source).
      const links = document.createElement("p");
      const play = document.createElement("button");
      play.type = "button";
      play.id = "sim-play-flight";
      const at = f.flown_min_distance_time_s;
      play.textContent = `Show this flight in 3D${f.seed != null ? ` (seed ${f.seed})` : ""}`
        + `${at != null ? ` at its closest pair, ${fmt(at, 1, " s")}` : ""}`;
      const showId = this.state.meta.id;
      play.addEventListener("click", async () => {
        const run = { job_id: jobId };
        if (this.hooks.onPlayRun) return this.hooks.onPlayRun(run, at);
        try {
          await api.loadPlayback(showId, "simulated", run);
        } catch (err) {
          this._message("report-bad", `Cannot play the flight: ${err.message}`);
        }
      });
      links.append(play);
      this.body.append(links);
    }
  }
}
