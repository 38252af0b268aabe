// @ts-check
// Fetch wrapper for the swarmshow REST API: JSON in and out, errors as ApiError with
// per-field messages taken from FastAPI's 422 `detail` (its `path`, or `loc` turned into a path).

import { namesPath } from "./errors.js";

const TOKEN_KEY = "swarmshow.token";

/** An HTTP error from the API, with the problems it names. */
export class ApiError extends Error {
  /**
   * @param {number} status HTTP status (0 for a network failure).
   * @param {string} message one line for the user.
   * @param {{path: string, msg: string}[]} problems field problems (path "" = not tied to a field).
   * @param {any} body the parsed response body, if any.
   */
  constructor(status, message, problems = [], body = null) {
    super(message);
    this.name = "ApiError";
    this.status = status;
    this.problems = problems;
    this.body = body;
  }
}

/**
 * ['body', 'show', 'formations', 2, 'points'] -> 'formations[2].points' (request wrappers dropped).
 * @param {Array<string|number>} loc
 * @returns {string}
 */
export function locToPath(loc) {
  const parts = [...loc];
  while (parts.length && ["body", "query", "path", "show"].includes(String(parts[0]))) parts.shift();
  let out = "";
  for (const p of parts) {
    if (typeof p === "number" || /^\d+$/.test(String(p))) out += `[${p}]`;
    else out += out ? `.${p}` : String(p);
  }
  return out;
}

/**
 * The field problems of an error body: `{detail: [...]}`, `{detail: "..."}` or `{detail: {...}}`.
 * @param {any} body
 * @returns {{path: string, msg: string, max_n?: number}[]}
 */
export function problemsOf(body) {
  const detail = body && typeof body === "object" ? body.detail ?? body.errors ?? body : body;
  const list = Array.isArray(detail) ? detail : detail && typeof detail === "object" && Array.isArray(detail.errors) ? detail.errors : null;
  if (list) {
    return list.map((d) => {
      if (typeof d === "string") return { path: "", msg: d };
      let path = typeof d.path === "string" ? d.path.replace(/^show\./, "") : locToPath(d.loc || []);
      return { ...d, path, msg: String(d.msg ?? d.message ?? "invalid") };
    });
  }
  if (typeof detail === "string") return [{ path: "", msg: detail }];
  if (detail && typeof detail === "object" && (detail.message || detail.msg)) return [{ path: "", msg: String(detail.message || detail.msg) }];
  return [];
}

function messageFor(status, problems, statusText) {
  if (problems.length) {
    const p = problems[0];
    // Some messages name their field already ("file: not a mesh", "formations[2].arrive_at_s = 64 s is ..."):
    // say it once.
    const head = p.path && !namesPath(p.msg, p.path) ? `${p.path}: ${p.msg}` : p.msg;
    return problems.length > 1 ? `${head} (and ${problems.length - 1} more)` : head;
  }
  if (status === 413) return "the upload is too large";
  if (status === 404) return "not found";
  return `${status} ${statusText || "error"}`.trim();
}

let tokenPrompt = null;

/**
 * Set the function asked for a token when the server answers 401 (returns a Promise of the token or null).
 * @param {() => Promise<string|null>} fn
 */
export function setTokenPrompt(fn) {
  tokenPrompt = fn;
}

/**
 * Trade the token for the server's short-lived HttpOnly cookie, which the 3D preview iframe, the
 * progress stream and the viewer's websocket carry (they cannot send an Authorization header).
 */
export async function startSession() {
  if (!sessionStorage.getItem(TOKEN_KEY)) return;
  try {
    await fetch("/api/session", { method: "POST", headers: authHeaders(), credentials: "same-origin" });
  } catch {
    // the next API call reports an unreachable server
  }
}

// A reload keeps the token (per tab) but the cookie may have expired: renew it now and every 20 min.
startSession();
setInterval(startSession, 20 * 60 * 1000);

function authHeaders() {
  const t = sessionStorage.getItem(TOKEN_KEY);
  return t ? { Authorization: `Bearer ${t}` } : {};
}

/**
 * One API request. JSON bodies via `json`, anything else (FormData, Blob) via `body`.
 * @param {string} method
 * @param {string} url same-origin path, e.g. "/api/shows"
 * @param {{json?: any, body?: BodyInit, headers?: Record<string,string>, raw?: boolean, signal?: AbortSignal}} [opts]
 * @returns {Promise<any>} parsed JSON (or the Response itself with `raw`)
 * @throws {ApiError}
 */
export async function request(method, url, opts = {}, retried = false) {
  const headers = { Accept: "application/json", ...authHeaders(), ...(opts.headers || {}) };
  let body = opts.body;
  if (opts.json !== undefined) {
    headers["Content-Type"] = "application/json";
    body = JSON.stringify(opts.json);
  }
  let res;
  try {
    res = await fetch(url, { method, headers, body, signal: opts.signal, credentials: "same-origin" });
  } catch (err) {
    if (err && err.name === "AbortError") throw err;
    throw new ApiError(0, "cannot reach the server (is it running?)");
  }
  if (res.status === 401 && !retried && tokenPrompt) {
    const token = await tokenPrompt();
    if (token) {
      sessionStorage.setItem(TOKEN_KEY, token);
      await startSession();
      return request(method, url, opts, true);
    }
  }
  if (!res.ok) {
    let parsed = null;
    try {
      parsed = await res.json();
    } catch {
      parsed = null;
    }
    const problems = problemsOf(parsed);
    // A refused draft says in plain words what is wrong with it (its `message`); else the first problem.
    const message = parsed && typeof parsed.message === "string" && parsed.draft ? parsed.message : messageFor(res.status, problems, res.statusText);
    throw new ApiError(res.status, message, problems, parsed);
  }
  if (opts.raw) return res;
  if (res.status === 204) return null;
  const type = res.headers.get("content-type") || "";
  return type.includes("json") ? res.json() : res.text();
}

/**
 * A stored show as the editor uses it: id, name, revision and the show document.
 * Accepts the record shapes `{id, revision, show}` and `{id, revision, ...showFields}`.
 * @param {any} r
 * @returns {{id: string, name: string, revision: number, show: any, updated_at?: string, draft: boolean, problems: any[]}}
 */
export function normalizeRecord(r) {
  let show = r.show ?? r.data ?? r.document ?? null;
  if (!show && r.json) show = typeof r.json === "string" ? JSON.parse(r.json) : r.json;
  if (!show && r.format) {
    const { id: _id, revision: _rev, created_at: _c, updated_at: _u, content_hash: _h, ...rest } = r;
    show = rest;
  }
  const problems = Array.isArray(r.problems) ? r.problems : [];
  return { id: r.id, name: r.name ?? show?.name ?? "", revision: r.revision, show, updated_at: r.updated_at, draft: !!r.draft, problems };
}

/** @returns {Promise<any[]>} stored show summaries (id, name, drones, formations, updated_at, revision). */
export async function listShows() {
  const out = [];
  for (let offset = 0; offset < 10000; ) {
    const page = await request("GET", `/api/shows?limit=200&offset=${offset}`);
    const items = Array.isArray(page) ? page : page.items ?? page.shows ?? [];
    out.push(...items);
    const total = Array.isArray(page) ? items.length : page.total ?? items.length;
    offset += items.length;
    if (!items.length || offset >= total) break;
  }
  return out;
}

/** @param {string} id @returns {Promise<ReturnType<typeof normalizeRecord>>} */
export async function getShow(id) {
  return normalizeRecord(await request("GET", `/api/shows/${encodeURIComponent(id)}`));
}

/**
 * Store a new show (with `draft`, one that breaks the rules is kept as a draft instead of refused).
 * @param {any} show a swarmshow/1 document
 * @param {{draft?: boolean}} [opts]
 * @returns {Promise<ReturnType<typeof normalizeRecord>>}
 */
export async function createShow(show, opts = {}) {
  const rec = normalizeRecord(await request("POST", `/api/shows${opts.draft ? "?draft=true" : ""}`, { json: show }));
  return rec.show ? rec : { ...rec, show };
}

/**
 * Give show `id` the music of show `fromId` (a copy made in the store). Resolves to the new track's
 * info, or null when `fromId` has no music (204: nothing to copy).
 * @param {string} id
 * @param {string} fromId
 * @returns {Promise<any>}
 */
export async function copyAudio(id, fromId) {
  const info = await request("POST", `/api/shows/${encodeURIComponent(id)}/audio/copy?from=${encodeURIComponent(fromId)}`);
  return info || null;
}

/**
 * Replace a show; `revision` is the one the edit is based on (a stale one gets 409). With `draft`,
 * a show that breaks the rules is stored as a draft (the answer lists its `problems`) instead of refused.
 * @param {string} id
 * @param {any} show
 * @param {number} revision
 * @param {{draft?: boolean}} [opts]
 * @returns {Promise<ReturnType<typeof normalizeRecord>>}
 */
export async function updateShow(id, show, revision, opts = {}) {
  const res = await request("PUT", `/api/shows/${encodeURIComponent(id)}${opts.draft ? "?draft=true" : ""}`, {
    json: { revision, show },
    headers: { "If-Match": `"${revision}"` },
  });
  const rec = normalizeRecord(res);
  return rec.show ? rec : { ...rec, show };
}

/** @param {string} id */
export function deleteShow(id) {
  return request("DELETE", `/api/shows/${encodeURIComponent(id)}`);
}

/** @param {string} id @returns {Promise<any>} the check result (a job result or the report itself). */
export function checkShow(id) {
  return request("POST", `/api/shows/${encodeURIComponent(id)}/check`, { json: {} });
}

/** @param {string} id @param {object} [options] @returns {Promise<any>} the job (202). */
export function simulateShow(id, options = {}) {
  return request("POST", `/api/shows/${encodeURIComponent(id)}/simulate`, { json: options });
}

/**
 * Start a Monte-Carlo job: the show flown `runs` times for its safety margin.
 * @param {string} id @param {{runs?: number, preset?: string, controller?: string, seed0?: number, confidence?: number}} [options]
 * @returns {Promise<any>} the job (202).
 */
export function monteCarloShow(id, options = {}) {
  return request("POST", `/api/shows/${encodeURIComponent(id)}/montecarlo`, { json: options });
}

/** @param {string} jobId @param {"html"|"pdf"} [format] @returns {string} the safety report of a Monte-Carlo job. */
export function safetyReportUrl(jobId, format = "html") {
  return `/api/jobs/${encodeURIComponent(jobId)}/report.${format}`;
}

/** @param {string} jobId */
export function getJob(jobId) {
  return request("GET", `/api/jobs/${encodeURIComponent(jobId)}`);
}

/** @param {string} jobId */
export function cancelJob(jobId) {
  return request("DELETE", `/api/jobs/${encodeURIComponent(jobId)}`);
}

/** @param {string} jobId @returns {string} the server-sent events URL of a job. */
export function jobEventsUrl(jobId) {
  return `/api/jobs/${encodeURIComponent(jobId)}/events`;
}

/**
 * Build formation points on the server.
 * @param {"shape"|"text"|"image"|"svg"} source
 * @param {object} params JSON parameters (n, plane, center_m, ...)
 * @param {File|Blob} [file] the upload for image and svg
 * @returns {Promise<{points: number[][], colors: string[], min_spacing_m: number|null, name: string}>}
 *   (`name`: after the source, the file's stem, the text or the shape's kind)
 */
export function buildFormation(source, params, file) {
  if (file) {
    const fd = new FormData();
    fd.append("file", file);
    for (const [k, v] of Object.entries(params)) {
      if (v !== undefined && v !== null) fd.append(k, typeof v === "object" ? JSON.stringify(v) : String(v));
    }
    return request("POST", `/api/formations/${source}`, { body: fd });
  }
  return request("POST", `/api/formations/${source}`, { json: params });
}

/**
 * @param {string} id @param {"planned"|"simulated"} [source]
 * @param {{job_id: string, run?: number}} [run] with "simulated": fly this run of a Monte-Carlo job, or (no
 *   `run`) the flight of this simulation job (its preset and seed)
 */
export function loadPlayback(id, source = "planned", run = undefined) {
  return request("POST", `/api/shows/${encodeURIComponent(id)}/playback`, { json: run ? { source, ...run } : { source } });
}

/**
 * Download an export.
 * @param {string} id
 * @param {string} format
 * @param {Record<string, string|number>} [options] query options (origin, heading_deg, fps, source)
 * @returns {Promise<{blob: Blob, filename: string, warnings: string[]}>}
 */
export async function exportShow(id, format, options = {}) {
  const query = new URLSearchParams();
  for (const [k, v] of Object.entries(options)) if (v !== "" && v != null) query.set(k, String(v));
  const qs = query.toString() ? `?${query}` : "";
  const res = await request("GET", `/api/shows/${encodeURIComponent(id)}/export/${encodeURIComponent(format)}${qs}`, {
    raw: true,
    headers: { Accept: "*/*" },
  });
  const blob = await res.blob();
  const cd = res.headers.get("content-disposition") || "";
  const m = /filename\*=UTF-8''([^;]+)/i.exec(cd) || /filename="?([^";]+)"?/i.exec(cd);
  const filename = m ? decodeURIComponent(m[1]) : `show.${format}`;
  let warnings = [];
  try {
    warnings = JSON.parse(res.headers.get("x-swarmshow-warnings") || "[]");
  } catch {
    warnings = [];
  }
  return { blob, filename, warnings };
}

/** The export formats the server registers (app.exports.EXPORT_FORMATS), used when the OpenAPI schema does not list them. */
export const DEFAULT_EXPORT_FORMATS = [
  "show", "skybrush-csv", "skyc", "crazyswarm", "qgc-plan", "qgc-wpl", "waypoints-csv", "viser-html",
];

/**
 * Export formats the server offers: the enum of the format path parameter in its OpenAPI schema,
 * else the list the server gives when asked for an unknown format, else this built-in list.
 * @returns {Promise<string[]>}
 */
export async function exportFormats() {
  try {
    const spec = await request("GET", "/api/openapi.json");
    for (const [path, item] of Object.entries(spec.paths || {})) {
      const m = /\/export\/\{([^}]+)\}$/.exec(path);
      if (!m || !item.get) continue;
      const p = (item.get.parameters || []).find((q) => q.name === m[1]);
      let schema = p && p.schema;
      if (schema && schema.$ref) schema = resolveRef(spec, schema.$ref);
      const en = schema && (schema.enum || (schema.anyOf || []).flatMap((s) => s.enum || []));
      if (en && en.length) return en;
    }
  } catch {
    // try the next source
  }
  try {
    await request("GET", "/api/shows/-/export/-");
  } catch (err) {
    const m = /one of: ([\w\s,.-]+)$/.exec(err.message || "");
    if (m) {
      const list = m[1].split(",").map((s) => s.trim()).filter(Boolean);
      if (list.length) return list;
    }
  }
  return DEFAULT_EXPORT_FORMATS;
}

function resolveRef(spec, ref) {
  return ref.replace(/^#\//, "").split("/").reduce((o, k) => (o ? o[k] : undefined), spec);
}

/**
 * Move the 3D playback of one viewer page (the editor's own preview pane): to a time or a formation's hold.
 * @param {string} token the page's token (see Preview.viewerState)
 * @param {{time_s?: number, formation?: number}} where
 */
export function viewerSeek(token, where) {
  return request("POST", `/api/viewer/${encodeURIComponent(token)}/seek`, { json: where });
}
