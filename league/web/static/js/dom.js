// Finding and building elements, message boxes, and the forms and buttons that only work once
// their page's script is ready. Text always goes in as text (textContent), never as markup.

export const $ = (id) => document.getElementById(id);

export function element(tag, { className, text, attrs } = {}, ...children) {
  const node = document.createElement(tag);
  if (className) node.className = className;
  if (text !== undefined && text !== null) node.textContent = text;
  for (const [name, value] of Object.entries(attrs || {})) {
    if (value !== undefined && value !== null && value !== false) node.setAttribute(name, value === true ? "" : value);
  }
  node.append(...children.filter((child) => child !== null && child !== undefined));
  return node;
}

export function badge(status, label = status) {
  return element("span", { className: `badge ${status}`, text: label });
}

/** Show a message in a message box (role="alert" boxes are read out by screen readers). */
export function say(box, text, kind = "error") {
  box.className = `message ${kind}`;
  box.textContent = text || "";
}

/**
 * Handle a form's submission in script. The pages' submit buttons are `disabled` in the HTML and
 * enabled here: before its page is ready, a click does nothing, where the browser's own
 * submission would reload the page and lose what was typed.
 */
export function onSubmit(form, handler) {
  form.addEventListener("submit", (event) => {
    event.preventDefault();
    handler(event);
  });
  form.querySelectorAll("button[type=submit]").forEach((button) => (button.disabled = false));
}

/** The same for a button outside a form: `disabled` in the HTML until it has its handler. */
export function onClick(button, handler) {
  button.addEventListener("click", handler);
  button.disabled = false;
}

/**
 * Move the keyboard focus to the result of an action (a heading, a new row, a message): what a
 * screen reader reads next, and where Tab goes on from. Elements that are not controls get
 * tabindex="-1": focusable by script, not a tab stop.
 */
export function focusOn(target) {
  if (!target) return;
  if (!target.matches("a[href], button, input, select, textarea, summary, [tabindex]")) target.tabIndex = -1;
  target.focus();
}

/**
 * Replace a container's content (a polled list, a re-drawn table) without losing the keyboard
 * focus: the element that had it passes it to its successor, the new element with the same
 * `data-focus-key`, or if there is none (a "Make active" button once it is), to the one its
 * `data-focus-next` names. Without this, every refresh would send a keyboard user to the top.
 */
export function replaceKeepingFocus(container, ...children) {
  const focused = container.contains(document.activeElement) ? document.activeElement.dataset : {};
  container.replaceChildren(...children);
  for (const key of [focused.focusKey, focused.focusNext]) {
    const successor = key && container.querySelector(`[data-focus-key="${CSS.escape(key)}"]`);
    if (successor) {
      successor.focus({ preventScroll: true });
      return;
    }
  }
}
