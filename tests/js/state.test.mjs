// Undo/redo of the editor state (frontend/js/state.js): per-formation diffs checked against
// whole-document snapshots taken independently after every edit.
import assert from "node:assert/strict";
import { test } from "node:test";

import { EditorState, spliceDiff } from "../../frontend/js/state.js";

function rng(seed) {
  let s = seed >>> 0;
  return () => ((s = (Math.imul(s, 1664525) + 1013904223) >>> 0) / 4294967296);
}

function formation(name, n, r) {
  return { name, hold_s: 5, points: Array.from({ length: n }, () => [r() * 50, r() * 50, 10 + r() * 50]),
    colors: Array.from({ length: n }, () => "#ffffff") };
}

function newShow(r, k = 4) {
  return { format: "swarmshow/1", name: "t", drones: 10, settings: { min_distance_m: 2 },
    home: { grid: { spacing_m: 3 } }, formations: Array.from({ length: k }, (_, i) => formation(`f${i}`, 10, r)) };
}

const text = (state) => JSON.stringify(state.show);

// One random edit of each kind the editor makes: move points, add/delete/move a formation, settings.
function randomEdit(state, r) {
  const fs = state.show.formations;
  const kind = Math.floor(r() * 6);
  if (kind === 0 || kind === 1) {
    const f = fs[Math.floor(r() * fs.length)];
    state.edit("Move point", () => { f.points[Math.floor(r() * f.points.length)][0] += 1 + r(); });
  } else if (kind === 2) {
    state.edit("Add formation", () => { fs.splice(Math.floor(r() * (fs.length + 1)), 0, formation(`n${r()}`, 10, r)); });
  } else if (kind === 3 && fs.length > 1) {
    state.edit("Delete formation", () => { fs.splice(Math.floor(r() * fs.length), 1); });
  } else if (kind === 4 && fs.length > 1) {
    const i = Math.floor(r() * fs.length);
    const j = Math.floor(r() * fs.length);
    state.edit("Move formation", () => { const [f] = fs.splice(i, 1); fs.splice(j, 0, f); });
  } else {
    state.edit("Settings", () => { state.show.settings = { ...state.show.settings, min_distance_m: 1 + r() * 3 }; });
  }
}

test("spliceDiff keeps the common prefix and suffix", () => {
  assert.deepEqual(spliceDiff(["a", "b", "c"], ["a", "x", "c"]), { start: 1, before: ["b"], after: ["x"] });
  assert.deepEqual(spliceDiff(["a", "b"], ["a", "b", "c"]), { start: 2, before: [], after: ["c"] });
  assert.deepEqual(spliceDiff(["a", "b", "c"], ["a", "c"]), { start: 1, before: ["b"], after: [] });
  assert.deepEqual(spliceDiff(["a"], ["a"]), { start: 1, before: [], after: [] });
});

test("undo and redo walk back and forth through exactly the documents the edits made", () => {
  for (const seed of [1, 2, 3, 4, 5]) {
    const r = rng(seed);
    const state = new EditorState();
    state.load(newShow(r), { id: "x", revision: 1 });
    const docs = [text(state)];
    for (let k = 0; k < 40; k++) {
      const steps = state.undoStack.length;
      randomEdit(state, r);
      if (state.undoStack.length > steps) docs.push(text(state)); // every recorded step, no-ops included
    }
    assert.ok(docs.length > 30);
    for (let k = docs.length - 2; k >= 0; k--) {
      assert.ok(state.undo());
      assert.equal(text(state), docs[k]);
    }
    assert.ok(!state.dirty);
    for (let k = 1; k < docs.length; k++) {
      assert.ok(state.redo());
      assert.equal(text(state), docs[k]);
    }
    assert.ok(!state.redo());
  }
});

test("a point edit stores one formation, not the document", () => {
  const r = rng(9);
  const state = new EditorState();
  state.load(newShow(r, 8), { id: "x", revision: 1 });
  const f = state.show.formations[5];
  state.edit("Move point", () => { f.points[0][2] += 1; });
  const step = state.undoStack[0];
  assert.equal(step.start, 5);
  assert.equal(step.before.length, 1);
  assert.equal(step.after.length, 1);
  assert.equal(step.restBefore, null);
  const stored = step.before[0].length + step.after[0].length;
  assert.ok(stored < JSON.stringify(state.show).length / 3, `${stored} bytes stored`);
  assert.equal(step.label, "Move point");
});

test("a rollback restores the checkpoint and a failed edit leaves no step", () => {
  const r = rng(10);
  const state = new EditorState();
  state.load(newShow(r), { id: "x", revision: 1 });
  const before = text(state);
  state.checkpoint();
  state.show.formations[0].points[0][0] = 999;
  state.show.settings.min_distance_m = 9;
  state.rollback();
  assert.equal(text(state), before);
  assert.throws(() => state.edit("Broken", () => { state.show.formations.pop(); throw new Error("boom"); }));
  assert.equal(text(state), before);
  assert.equal(state.undoStack.length, 0);
});

test("a hold or transition duration the show file refuses is named before it is stored", async () => {
  const { durationProblem, MIN_DURATION_S, MAX_DURATION_S } = await import("../../frontend/js/state.js");
  for (const ok of [MIN_DURATION_S, 0.5, 5, MAX_DURATION_S]) assert.equal(durationProblem(ok), "", String(ok));
  for (const bad of [0, -1, MIN_DURATION_S / 2, MAX_DURATION_S + 0.5, 1e9, NaN, Infinity]) {
    assert.notEqual(durationProblem(bad), "", String(bad));
  }
  assert.match(durationProblem(1e9), /at most 86400 s/);
  assert.match(durationProblem(0), /at least 0.01 s/);
});
