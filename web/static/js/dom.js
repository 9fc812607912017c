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
