// Unit tests of frontend/js/hidpi.js's fitCanvas on a recording stand-in for a canvas (node has no DOM).
import assert from "node:assert/strict";
import { test } from "node:test";

import { fitCanvas } from "../../frontend/js/hidpi.js";

/** A canvas stand-in that records the backing-store assignments and the context calls. */
function fakeCanvas(cssW, cssH, storeW = 300, storeH = 150) {
  const log = [];
  let width = storeW;
  let height = storeH;
  const ctx = {
    setTransform: (...a) => log.push(["setTransform", ...a]),
    clearRect: (...a) => log.push(["clearRect", ...a]),
  };
  return {
    log,
    clientWidth: cssW,
    clientHeight: cssH,
    get width() { return width; },
    set width(v) { log.push(["width", v]); width = v; },
    get height() { return height; },
    set height(v) { log.push(["height", v]); height = v; },
    getContext: (kind) => (kind === "2d" ? ctx : null),
    ctx,
  };
}

test("fitCanvas sizes the store to CSS size x dpr, scales and clears the context in CSS pixels", () => {
  for (const [w, h, dpr] of [[640, 120, 1], [333, 47, 1.5], [801, 99, 2], [10, 10, 2.625]]) {
    const c = fakeCanvas(w, h);
    const fit = fitCanvas(c, dpr);
    assert.equal(fit.g, c.ctx);
    assert.deepEqual([fit.w, fit.h], [w, h]);
    assert.equal(c.width, Math.round(w * dpr));
    assert.equal(c.height, Math.round(h * dpr));
    assert.deepEqual(c.log.slice(-2), [["setTransform", dpr, 0, 0, dpr, 0, 0], ["clearRect", 0, 0, w, h]]);
  }
});

test("fitCanvas leaves a store of the right size alone (assigning one clears and reallocates it)", () => {
  const c = fakeCanvas(200, 50, 400, 100);
  fitCanvas(c, 2);
  assert.deepEqual(c.log.map((e) => e[0]), ["setTransform", "clearRect"]);
  // One side off: both are assigned.
  const d = fakeCanvas(200, 50, 400, 99);
  fitCanvas(d, 2);
  assert.deepEqual(d.log.map((e) => e[0]), ["width", "height", "setTransform", "clearRect"]);
});

test("fitCanvas draws nothing on a canvas with no size (hidden)", () => {
  for (const [w, h] of [[0, 50], [50, 0], [0, 0]]) {
    const c = fakeCanvas(w, h);
    assert.equal(fitCanvas(c, 2), null);
    assert.deepEqual(c.log, []);
  }
});

test("fitCanvas defaults to the device pixel ratio, 1 where there is none", () => {
  const had = "devicePixelRatio" in globalThis;
  const old = globalThis.devicePixelRatio;
  try {
    globalThis.devicePixelRatio = 3;
    const c = fakeCanvas(20, 10);
    fitCanvas(c);
    assert.deepEqual([c.width, c.height], [60, 30]);
    delete globalThis.devicePixelRatio;
    const d = fakeCanvas(20, 10);
    fitCanvas(d);
    assert.deepEqual([d.width, d.height], [20, 10]);
  } finally {
    if (had) globalThis.devicePixelRatio = old;
    else delete globalThis.devicePixelRatio;
  }
});
