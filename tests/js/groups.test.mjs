// Drone groups in the editor (frontend/js/groups.js): one lookup over the show's groups and the older
// lights.groups, renames that follow every reference, and the light preview with drones out of a formation.
import assert from "node:assert/strict";
import { test } from "node:test";

import { allGroups, flyingCount, groupUses, putGroup, removeGroup, renameGroup } from "../../frontend/js/groups.js";
import { evaluatePlanned } from "../../frontend/js/lighteval.js";

function show() {
  return {
    drones: 6,
    groups: { front: [0, 1] },
    formations: [{ name: "a", points: [], drones: { group: "front" }, others: "park" }, { name: "b", points: [] },
      { name: "c", points: [], drones: { count: 4 } }],
    lights: { groups: { old: [5, 4] }, effects: [{ target: { kind: "group", group: "old" } }] },
  };
}

test("the show's groups over lights.groups, as ShowFile.drone_groups", () => {
  const s = show();
  assert.deepEqual(allGroups(s), { old: [5, 4], front: [0, 1] });
  s.lights.groups.front = [3];
  assert.deepEqual(allGroups(s).front, [0, 1]);
  assert.deepEqual(allGroups(null), {});
});

test("flying count: group size, count, or every drone", () => {
  const s = show();
  assert.deepEqual(s.formations.map((f) => flyingCount(s, f)), [2, 6, 4]);
});

test("rename follows formations and effects, and moves an older group up to the show's groups", () => {
  const s = show();
  renameGroup(s, "old", "back");
  renameGroup(s, "front", "row 1");
  assert.deepEqual(s.groups, { back: [4, 5], "row 1": [0, 1] });
  assert.deepEqual(s.lights.groups, {});
  assert.deepEqual(s.formations[0].drones, { group: "row 1" });
  assert.equal(s.formations[0].others, "park");
  assert.deepEqual(s.lights.effects[0].target, { kind: "group", group: "back" });
  assert.deepEqual(groupUses(s, "row 1"), ['formation "a"']);
  assert.deepEqual(groupUses(s, "back"), ["a light effect"]);
});

test("put dedupes and sorts; remove drops an emptied groups block", () => {
  const s = show();
  putGroup(s, "x", [3, 2, 3]);
  assert.deepEqual(s.groups.x, [2, 3]);
  removeGroup(s, "x");
  removeGroup(s, "front");
  assert.equal("groups" in s, false);
});

test("planned preview: drones out of the formation (-1) paint no point and do not break the preview", () => {
  const s = { drones: 3, formations: [{ name: "a", points: [[0, 0, 10], [5, 0, 10]] }],
    lights: { effects: [{ start_s: 0, end_s: 100, target: { kind: "all" }, effect: { kind: "solid", color: "#00ff00" } }] } };
  const plan = { drones: 3, assignment: [[1, -1, 0]], segments: [{ kind: "transition", label: "a", start_s: 0, duration_s: 5 },
    { kind: "hold", label: "a", start_s: 5, duration_s: 5 }] };
  const out = evaluatePlanned(s, 0, s.formations[0].points, [[1, 0, 0], [1, 0, 0]], 6, plan);
  assert.deepEqual(out, [[0, 1, 0], [0, 1, 0]]);
});
