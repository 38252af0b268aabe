// @ts-check
// Keyboard shortcuts, one table used both to handle keys and to fill the help panel.

/**
 * @typedef {{keys: string, label: string, match: (e: KeyboardEvent) => boolean, run: () => void,
 *            inText?: boolean}} Shortcut
 */

const mod = (e) => e.ctrlKey || e.metaKey;
const plain = (e) => !e.ctrlKey && !e.metaKey && !e.altKey;

/**
 * The shortcut table.
 * @param {Record<string, (...args: any[]) => void>} a actions by name (``tool`` takes the tool's name)
 * @returns {Shortcut[]}
 */
export function shortcutTable(a) {
  const key = (k) => (e) => plain(e) && e.key.toLowerCase() === k;
  return [
    { keys: "Ctrl+S", label: "Save", match: (e) => mod(e) && e.key.toLowerCase() === "s", run: a.save, inText: true },
    { keys: "Ctrl+Z", label: "Undo", match: (e) => mod(e) && !e.shiftKey && e.key.toLowerCase() === "z", run: a.undo },
    { keys: "Ctrl+Shift+Z, Ctrl+Y", label: "Redo", match: (e) => mod(e) && ((e.shiftKey && e.key.toLowerCase() === "z") || e.key.toLowerCase() === "y"), run: a.redo },
    { keys: "Ctrl+O", label: "Shows (open, create, import)", match: (e) => mod(e) && e.key.toLowerCase() === "o", run: a.shows, inText: true },
    { keys: "Ctrl+Enter", label: "Check the show", match: (e) => mod(e) && e.key === "Enter", run: a.check, inText: true },
    { keys: "Ctrl+E", label: "Export in the chosen format", match: (e) => mod(e) && e.key.toLowerCase() === "e", run: a.exportNow, inText: true },
    { keys: "P", label: "3D preview on/off", match: key("p"), run: a.preview },
    { keys: "S", label: "Select / move tool", match: key("s"), run: () => a.tool("select") },
    { keys: "D", label: "Draw tool (Shift+drag adds a stroke)", match: key("d"), run: () => a.tool("draw") },
    { keys: "A", label: "Place points tool", match: key("a"), run: () => a.tool("place") },
    { keys: "X", label: "Delete points tool", match: key("x"), run: () => a.tool("erase") },
    { keys: "H", label: "Pan tool (or Space+drag, middle-drag)", match: key("h"), run: () => a.tool("pan") },
    { keys: "V", label: "Front / top view", match: (e) => key("v")(e) && !e.shiftKey, run: a.toggleView },
    { keys: "Shift+V", label: "Side / 3D view", match: (e) => key("v")(e) && e.shiftKey, run: a.toggleView3d },
    { keys: "F", label: "Zoom to fit", match: key("f"), run: a.fit },
    { keys: "+ / −, wheel", label: "Zoom in / out", match: (e) => plain(e) && ["+", "=", "-", "_"].includes(e.key), run: () => {} },
    { keys: "Ctrl+A", label: "Select all points", match: (e) => mod(e) && e.key.toLowerCase() === "a", run: a.selectAll },
    { keys: "Esc", label: "Cancel the gesture / clear the selection", match: (e) => e.key === "Escape", run: a.escape },
    { keys: "Delete, Backspace", label: "Delete the selected points", match: (e) => plain(e) && (e.key === "Delete" || e.key === "Backspace"), run: a.deleteSelection },
    { keys: "Arrows", label: "Nudge the selection 1 m (Shift: 5 m, Alt: 0.1 m)", match: (e) => !mod(e) && e.key.startsWith("Arrow"), run: () => {} },
    { keys: "[ / ]", label: "Rotate the selection 5° left / right", match: (e) => plain(e) && (e.key === "[" || e.key === "]"), run: () => {} },
    { keys: "< / >", label: "Shrink / grow the selection 10%", match: (e) => !mod(e) && (e.key === "<" || e.key === ">"), run: () => {} },
    { keys: "N", label: "Add a formation", match: key("n"), run: a.addFormation },
    { keys: "Ctrl+D", label: "Duplicate the formation", match: (e) => mod(e) && e.key.toLowerCase() === "d", run: a.duplicate },
    { keys: "PageUp / PageDown", label: "Previous / next formation", match: (e) => plain(e) && (e.key === "PageUp" || e.key === "PageDown"), run: () => {} },
    { keys: "Alt+← / Alt+→", label: "Move the formation earlier / later", match: (e) => e.altKey && !mod(e) && (e.key === "ArrowLeft" || e.key === "ArrowRight"), run: () => {} },
    { keys: "?", label: "This help", match: (e) => e.key === "?", run: a.help },
  ];
}

function inTextField(el) {
  if (!el) return false;
  const tag = el.tagName;
  if (tag === "TEXTAREA" || tag === "SELECT" || el.isContentEditable) return true;
  if (tag !== "INPUT") return false;
  return !["button", "checkbox", "radio", "color", "file", "range"].includes(el.type);
}

/**
 * Listen for shortcuts. Keys with a direction or amount go to `a.keyed(e)`.
 * @param {Record<string, any>} a actions (see {@link shortcutTable}) plus `keyed(e)`
 * @returns {Shortcut[]} the table, for the help panel
 */
export function installShortcuts(a) {
  const table = shortcutTable(a);
  window.addEventListener("keydown", (e) => {
    if (document.querySelector("dialog[open]") && e.key !== "Escape") return;
    const typing = inTextField(/** @type {HTMLElement} */ (document.activeElement));
    for (const s of table) {
      if (!s.match(e)) continue;
      if (typing && !s.inText) return;
      if (e.key === "Escape" && document.querySelector("dialog[open]")) return;
      e.preventDefault();
      s.run();
      a.keyed(e);
      return;
    }
  });
  return table;
}

/**
 * Fill the help table.
 * @param {HTMLTableElement} table
 * @param {Shortcut[]} shortcuts
 */
export function renderHelp(table, shortcuts) {
  table.replaceChildren();
  for (const s of shortcuts) {
    const tr = document.createElement("tr");
    const k = document.createElement("td");
    for (const [i, part] of s.keys.split(", ").entries()) {
      if (i) k.append(", ");
      const kbd = document.createElement("kbd");
      kbd.textContent = part;
      k.append(kbd);
    }
    const l = document.createElement("td");
    l.textContent = s.label;
    tr.append(k, l);
    table.append(tr);
  }
}
