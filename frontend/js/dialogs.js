// @ts-check
// Small modal helpers: a choice among buttons (optionally with a text field) and a passing toast.

let toastTimer = 0;

/**
 * Show a short message at the bottom of the screen.
 * @param {string} message
 * @param {{error?: boolean, ms?: number}} [opts]
 */
export function toast(message, opts = {}) {
  const el = document.getElementById("toast");
  el.textContent = message;
  el.classList.toggle("error", !!opts.error);
  el.hidden = false;
  clearTimeout(toastTimer);
  toastTimer = setTimeout(() => { el.hidden = true; }, opts.ms ?? (opts.error ? 6000 : 2500));
}

/**
 * Ask the user to choose. Resolves with the chosen button's value, or null if the dialog is dismissed (Escape).
 * @param {{title: string, message: string, buttons: {label: string, value: string, primary?: boolean}[],
 *          input?: {label: string, value: string}, validate?: (text: string) => string|null}} spec
 *   validate: what is wrong with the text when the "ok" button is pressed (the dialog stays open saying so), or null
 * @returns {Promise<{choice: string|null, text: string}>}
 */
export function choose(spec) {
  const dlg = /** @type {HTMLDialogElement} */ (document.getElementById("dlg-confirm"));
  document.getElementById("dlg-confirm-h").textContent = spec.title;
  document.getElementById("dlg-confirm-msg").textContent = spec.message;
  const row = document.getElementById("confirm-input-row");
  const input = /** @type {HTMLInputElement} */ (document.getElementById("confirm-input"));
  row.hidden = !spec.input;
  if (spec.input) {
    document.getElementById("confirm-input-label").textContent = spec.input.label;
    input.value = spec.input.value;
    input.setAttribute("aria-label", spec.input.label);
  }
  const box = document.getElementById("confirm-buttons");
  box.replaceChildren();
  for (const b of spec.buttons) {
    const btn = document.createElement("button");
    btn.type = "submit";
    btn.value = b.value;
    btn.textContent = b.label;
    btn.setAttribute("aria-label", b.label);
    if (b.primary) btn.classList.add("primary");
    box.append(btn);
  }
  const error = document.getElementById("confirm-error");
  error.textContent = "";
  const form = /** @type {HTMLFormElement} */ (document.getElementById("form-confirm"));
  /** @param {SubmitEvent} e */
  const check = (e) => {
    const button = /** @type {HTMLButtonElement|null} */ (e.submitter);
    const problem = spec.validate && button && button.value === "ok" ? spec.validate(input.value) : null;
    if (!problem) return;
    e.preventDefault(); // the dialog stays open with the typed text and what is wrong with it
    error.textContent = problem;
    input.focus();
  };
  form.addEventListener("submit", check);
  return new Promise((resolve) => {
    dlg.returnValue = "";
    dlg.addEventListener("close", () => {
      form.removeEventListener("submit", check);
      error.textContent = "";
      resolve({ choice: dlg.returnValue || null, text: input.value });
    }, { once: true });
    dlg.showModal();
    if (spec.input) input.select();
    else /** @type {HTMLElement|null} */ (box.querySelector(".primary, button"))?.focus();
  });
}

/**
 * Yes/no confirmation.
 * @param {string} title @param {string} message @param {string} [ok]
 * @returns {Promise<boolean>}
 */
export async function confirmAction(title, message, ok = "OK") {
  const { choice } = await choose({ title, message, buttons: [{ label: ok, value: "ok", primary: true }, { label: "Cancel", value: "cancel" }] });
  return choice === "ok";
}

/**
 * Ask for a line of text.
 * @param {string} title @param {string} label @param {string} value
 * @param {{allowBlank?: boolean, validate?: (text: string) => string|null}} [opts] allowBlank: an empty answer is ""
 *   rather than null; validate: what is wrong with the trimmed text (the dialog stays open), or null
 * @returns {Promise<string|null>} the trimmed text, or null if cancelled (or blank, unless allowed)
 */
export async function askText(title, label, value, opts = {}) {
  const validate = opts.validate;
  const { choice, text } = await choose({
    title, message: "", input: { label, value },
    validate: validate ? (t) => (t.trim() === "" ? null : validate(t.trim())) : undefined,
    buttons: [{ label: "OK", value: "ok", primary: true }, { label: "Cancel", value: "cancel" }],
  });
  if (choice !== "ok") return null;
  return text.trim() || opts.allowBlank ? text.trim() : null;
}
