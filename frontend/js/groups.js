// @ts-check
// Drone groups and subset formations (issue 21): the show's named groups (create from the selection,
// rename, delete) and, per formation, which drones fly it (all, a group or a count) and what the
// others do (hold where they are, park behind the formation, or land on their homes).

/**
 * Every named group: the show's `groups` over the older `lights.groups` (as the server's ShowFile.drone_groups).
 * @param {any} show
 * @returns {Record<string, number[]>}
 */
export function allGroups(show) {
  if (!show) return {};
  return { ...((show.lights && show.lights.groups) || {}), ...(show.groups || {}) };
}

/**
 * How many drones fly formation `f`: its group's size, its count, or every drone.
 * @param {any} show
 * @param {any} f
 * @returns {number}
 */
export function flyingCount(show, f) {
  const sel = f && f.drones;
  if (sel && "group" in sel) return (allGroups(show)[sel.group] || []).length || show.drones;
  if (sel && "count" in sel) return Math.min(sel.count, show.drones);
  return show.drones;
}

/**
 * Where group `name` is used: formations flying it and light effects targeting it (plain words).
 * @param {any} show
 * @param {string} name
 * @returns {string[]}
 */
export function groupUses(show, name) {
  const out = [];
  for (const f of show.formations || []) if (f.drones && f.drones.group === name) out.push(`formation "${f.name}"`);
  const fx = (show.lights && show.lights.effects) || [];
  if (fx.some((/** @type {any} */ e) => e.target && e.target.kind === "group" && e.target.group === name)) {
    out.push("a light effect");
  }
  return out;
}

/**
 * Store group `name` = `drones` in the show's top-level `groups` (call inside `state.edit`). A group of the same
 * name in the older `lights.groups` moves up (one definition per name, as the server requires).
 * @param {any} show
 * @param {string} name
 * @param {number[]} drones
 */
export function putGroup(show, name, drones) {
  show.groups = { ...(show.groups || {}), [name]: [...new Set(drones)].sort((a, b) => a - b) };
  if (show.lights && show.lights.groups && name in show.lights.groups) {
    const g = { ...show.lights.groups };
    delete g[name];
    show.lights = { ...show.lights, groups: g };
  }
}

/**
 * Rename group `from` to `to` everywhere it is used (call inside `state.edit`).
 * @param {any} show
 * @param {string} from
 * @param {string} to
 */
export function renameGroup(show, from, to) {
  const drones = allGroups(show)[from];
  if (!drones) return;
  removeGroup(show, from);
  putGroup(show, to, drones);
  show.formations = show.formations.map((/** @type {any} */ f) =>
    (f.drones && f.drones.group === from ? { ...f, drones: { group: to } } : f));
  if (show.lights && Array.isArray(show.lights.effects)) {
    show.lights = {
      ...show.lights,
      effects: show.lights.effects.map((/** @type {any} */ e) =>
        (e.target && e.target.kind === "group" && e.target.group === from ? { ...e, target: { ...e.target, group: to } } : e)),
    };
  }
}

/**
 * Delete group `name` from wherever it is defined (call inside `state.edit`).
 * @param {any} show
 * @param {string} name
 */
export function removeGroup(show, name) {
  if (show.groups && name in show.groups) {
    const g = { ...show.groups };
    delete g[name];
    if (Object.keys(g).length) show.groups = g;
    else delete show.groups;
  }
  if (show.lights && show.lights.groups && name in show.lights.groups) {
    const g = { ...show.lights.groups };
    delete g[name];
    show.lights = { ...show.lights, groups: g };
  }
}

export class GroupsPanel {
  /**
   * @param {HTMLElement} root
   * @param {import("./state.js").EditorState} state
   * @param {{toast?: (msg: string, opts?: any) => void, selectedDrones: () => number[],
   *          ask?: (title: string, label: string, value: string) => Promise<string|null>,
   *          created?: (name: string) => void}} hooks
   */
  constructor(root, state, hooks) {
    this.root = root;
    this.state = state;
    this.hooks = hooks;
    this._build();
    state.addEventListener("change", (/** @type {any} */ e) => {
      if (e.detail.kind !== "live" && e.detail.kind !== "history") this.render();
    });
    this.render();
  }

  _build() {
    this.root.innerHTML = `
      <div class="row"><input id="grp-name" type="text" maxlength="200" placeholder="group name" aria-label="New drone group name">
        <button id="grp-add" type="button" aria-label="Make a drone group from the selection">Group from selection</button></div>
      <ul id="grp-list" class="fx-list" aria-label="Drone groups"></ul>
      <div class="row"><label for="grp-uses">Formation uses</label>
        <select id="grp-uses" aria-label="Drones flying this formation"><option value="all">all drones</option>
          <option value="group">a group</option><option value="count">a count</option></select>
        <select id="grp-group" aria-label="Group flying this formation"></select>
        <input id="grp-count" type="number" min="1" step="1" aria-label="How many drones fly this formation"></div>
      <div class="row"><label for="grp-others">Others</label>
        <select id="grp-others" aria-label="What the other drones do"><option value="hold">hold where they are</option>
          <option value="park">park behind the formation</option><option value="land">land on their homes</option></select></div>
      <p class="field-error" data-error-for="groups" role="alert"></p>`;
    const q = (/** @type {string} */ sel) => /** @type {any} */ (this.root.querySelector(sel));
    this.$name = q("#grp-name");
    this.$add = q("#grp-add");
    this.$list = q("#grp-list");
    this.$uses = q("#grp-uses");
    this.$group = q("#grp-group");
    this.$count = q("#grp-count");
    this.$others = q("#grp-others");
    this.$add.addEventListener("click", () => this.create(this.$name.value));
    this.$uses.addEventListener("change", () => this.setUses(this.$uses.value));
    this.$group.addEventListener("change", () => this.setUses("group"));
    this.$count.addEventListener("change", () => this.setUses("count"));
    this.$others.addEventListener("change", () => this.setOthers(this.$others.value));
  }

  /** @param {string} msg */
  _toast(msg) { this.hooks.toast?.(msg, { error: true }); }

  /**
   * A group of the drones behind the selected points (the last check's assignment; else drone i on point i).
   * @param {string} name
   */
  create(name) {
    const s = this.state.show;
    name = String(name || "").trim();
    const drones = this.hooks.selectedDrones();
    if (!s) return;
    if (!name) { this._toast("Name the group first"); return; }
    if (!drones.length) { this._toast("Select the points whose drones form the group"); return; }
    this.state.edit(`Group "${name}" (${drones.length} drones)`, () => { putGroup(s, name, drones); });
    this.$name.value = "";
    this.hooks.created?.(name);
  }

  /**
   * @param {string} from
   * @param {string} to
   */
  rename(from, to) {
    const s = this.state.show;
    to = String(to || "").trim();
    if (!s || !to || to === from) return;
    if (to in allGroups(s)) { this._toast(`There is a group "${to}" already`); return; }
    this.state.edit(`Rename group "${from}" to "${to}"`, () => { renameGroup(s, from, to); });
  }

  /** @param {string} name */
  remove(name) {
    const s = this.state.show;
    if (!s || !(name in allGroups(s))) return;
    const uses = groupUses(s, name);
    if (uses.length) { this._toast(`Group "${name}" is used by ${uses.join(" and ")}`); return; }
    this.state.edit(`Remove group "${name}"`, () => { removeGroup(s, name); });
  }

  /**
   * Who flies the current formation: "all", "group" (the group chosen in the panel) or "count".
   * @param {string} kind
   */
  setUses(kind) {
    const s = this.state.show;
    const f = this.state.formation;
    if (!s || !f) return;
    const groups = Object.keys(allGroups(s));
    /** @type {any} */
    let drones = null;
    if (kind === "group") {
      const name = this.$group.value || groups[0];
      if (!name) { this._toast("Make a group first (select points, name it, Group from selection)"); this.render(); return; }
      drones = { group: name };
    } else if (kind === "count") {
      const n = Math.round(Number(this.$count.value) || Math.min(s.drones, f.points.length));
      drones = { count: Math.max(1, n) };
    }
    const k = this.state.current;
    this.state.edit(`Formation "${f.name}" uses ${drones ? JSON.stringify(drones) : "all drones"}`, () => {
      const g = { ...s.formations[k] };
      if (drones) g.drones = drones;
      else { delete g.drones; delete g.others; }
      s.formations[k] = g;
    });
  }

  /** @param {string} what "hold", "park" or "land" */
  setOthers(what) {
    const s = this.state.show;
    const f = this.state.formation;
    if (!s || !f) return;
    const k = this.state.current;
    this.state.edit(`Others ${what} during "${f.name}"`, () => {
      const g = { ...s.formations[k] };
      if (what === "park" || what === "land") g.others = what;
      else delete g.others;
      s.formations[k] = g;
    });
  }

  render() {
    const s = this.state.show;
    const groups = allGroups(s);
    this.$add.disabled = !s || !this.state.selection.size;
    this.$list.replaceChildren(...Object.entries(groups).map(([name, idx]) => {
      const li = document.createElement("li");
      li.textContent = `${name} · ${idx.length} drones `;
      const ren = document.createElement("button");
      ren.type = "button";
      ren.textContent = "✎";
      ren.setAttribute("aria-label", `Rename group ${name}`);
      ren.addEventListener("click", async () => {
        const to = this.hooks.ask ? await this.hooks.ask(`Rename group "${name}"`, "New name", name) : null;
        if (to !== null) this.rename(name, to);
      });
      const del = document.createElement("button");
      del.type = "button";
      del.textContent = "×";
      del.setAttribute("aria-label", `Remove group ${name}`);
      del.addEventListener("click", () => this.remove(name));
      li.append(ren, del);
      return li;
    }));
    const f = this.state.formation;
    const sel = f && f.drones;
    const kind = !sel ? "all" : ("group" in sel ? "group" : "count");
    this.$uses.value = kind;
    this.$uses.disabled = !f;
    this.$group.replaceChildren(...Object.keys(groups).map((name) => {
      const o = document.createElement("option");
      o.value = name;
      o.textContent = `${name} (${groups[name].length})`;
      return o;
    }));
    if (sel && "group" in sel) this.$group.value = sel.group;
    this.$group.hidden = kind !== "group";
    this.$count.hidden = kind !== "count";
    if (sel && "count" in sel) this.$count.value = String(sel.count);
    if (s) this.$count.max = String(s.drones);
    this.$others.value = (f && f.others) || "hold";
    this.$others.disabled = kind === "all";
  }
}
