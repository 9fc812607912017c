// The course's assignments: the list with their times (in the viewer's zone), creating one, publishing
// (after a confirmation: nothing unpublishes).

import { api } from "../api.js";
import { $, element, focusOn, onClick, onSubmit, replaceKeepingFocus, say } from "../dom.js";
import { zonedTime } from "../format.js";

/** A datetime-local field's value as an ISO time with the browser's zone (null when empty). */
function fieldTime(id) {
  const value = $(id).value;
  return value ? new Date(value).toISOString() : null;
}

export async function setUpAssignments() {
  onSubmit($("assignment-form"), async () => {
    const body = {
      name: $("assignment-name").value.trim(), episodes: Number($("assignment-episodes").value),
      seed: Number($("assignment-seed").value), auto_publish: $("assignment-auto-publish").checked,
    };
    for (const [key, id] of [["opens_at", "assignment-opens"], ["due_at", "assignment-due"]]) {
      const time = fieldTime(id);
      if (time) body[key] = time;
    }
    try {
      const created = await api("/api/assignments", { method: "POST", json: body });
      say($("assignment-message"), `Created ${created.name}.`, "success");
      $("assignment-form").reset();
      await refresh();
    } catch (error) {
      say($("assignment-message"), `Not created: ${error.message}`, "error");
    }
  });
  await refresh();
}

async function refresh() {
  const assignments = await api("/api/assignments");
  replaceKeepingFocus($("assignments").tBodies[0], ...assignments.map((a) => {
    const action = a.published_at
      ? element("span", { className: "muted", text: "published", attrs: { "data-focus-key": `published-${a.id}` } })
      : element("button", { className: "secondary small", text: "Publish",
        attrs: { type: "button", "aria-label": `Publish ${a.name}`, "data-focus-key": `publish-${a.id}` } });
    if (!a.published_at) onClick(action, () => publish(a, action));
    return element("tr", {}, element("td", { text: a.name }), element("td", { text: zonedTime(a.opens_at) }),
      element("td", { text: zonedTime(a.due_at) }), element("td", { text: zonedTime(a.late_until) }),
      element("td", { text: String(a.seed) }), element("td", { text: String(a.private_seed ?? "–") }),
      element("td", { text: zonedTime(a.published_at) }), element("td", {}, action));
  }));
}

/** Publish once the dialog is confirmed; the focus then goes to the row's "published", or back to the button. */
async function publish(assignment, button) {
  if (!(await askToPublish(assignment))) {
    button.focus();
    return;
  }
  button.disabled = true; // which takes its focus: given to the outcome below
  try {
    await api(`/api/assignments/${assignment.id}/publish`, { method: "POST" });
    say($("assignment-message"), `Published ${assignment.name}: the students see the private board.`, "success");
    await refresh();
    focusOn($("assignments").querySelector(`[data-focus-key="published-${assignment.id}"]`));
  } catch (error) {
    say($("assignment-message"), `Not published: ${error.message}`, "error");
    button.disabled = false;
    button.focus();
  }
}

/** Publishing cannot be undone: a dialog says what the students will see, its Cancel button focused. */
function askToPublish(assignment) {
  const dialog = $("publish-dialog");
  $("publish-title").textContent = `Publish ${assignment.name}?`;
  $("publish-summary").textContent = `The students see ${assignment.name}'s private board and its private tracks ` +
    "(their seed) and, once it has a rubric, their own grades. Publishing cannot be undone.";
  dialog.returnValue = "";
  dialog.showModal();
  return new Promise((resolve) => {
    dialog.addEventListener("close", () => resolve(dialog.returnValue === "publish"), { once: true });
  });
}
