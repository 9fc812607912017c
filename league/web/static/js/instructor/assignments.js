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
      $("assignment-form").reset();
      const assignments = await refresh();
      const automatic = assignments.find((a) => a.automatic && !a.keep_open);
      say($("assignment-message"), `Created ${created.name}.` + (automatic ? ` The automatic assignment ` +
        `${automatic.name} no longer takes uploads (tick “Keep open” on its line to keep it).` : ""), "success");
    } catch (error) {
      say($("assignment-message"), `Not created: ${error.message}`, "error");
    }
  });
  await refresh();
}

/** The list (returned): the automatic assignment's line says whether it takes uploads, with its switch. */
async function refresh() {
  const assignments = await api("/api/assignments");
  const ownOnes = assignments.some((a) => !a.automatic);
  replaceKeepingFocus($("assignments").tBodies[0], ...assignments.map((a) => {
    const action = a.published_at
      ? element("span", { className: "muted", text: "published", attrs: { "data-focus-key": `published-${a.id}` } })
      : element("button", { className: "secondary small", text: "Publish",
        attrs: { type: "button", "aria-label": `Publish ${a.name}`, "data-focus-key": `publish-${a.id}` } });
    if (!a.published_at) onClick(action, () => publish(a, action));
    return element("tr", { attrs: { "data-assignment": a.id } }, nameCell(a, ownOnes),
      element("td", { text: zonedTime(a.opens_at) }),
      element("td", { text: zonedTime(a.due_at) }), element("td", { text: zonedTime(a.late_until) }),
      element("td", { text: String(a.seed) }), element("td", { text: String(a.private_seed ?? "–") }),
      element("td", { text: zonedTime(a.published_at) }), element("td", {}, action));
  }));
  return assignments;
}

function nameCell(assignment, ownOnes) {
  if (!assignment.automatic) return element("td", { text: assignment.name });
  const box = element("input", { attrs: { type: "checkbox", id: `keep-open-${assignment.id}`,
    "data-focus-key": `keep-open-${assignment.id}` } });
  box.checked = assignment.keep_open;
  box.addEventListener("change", () => keepOpen(assignment, box));
  const uploads = !ownOnes ? "takes uploads until you create an assignment"
    : assignment.keep_open ? "kept open beside your assignments" : "closed to uploads: your assignments replaced it";
  return element("td", {}, element("span", { text: assignment.name }),
    element("span", { className: "small muted", attrs: { "data-uploads": "" }, text: ` (automatic: ${uploads})` }),
    element("label", { className: "checks small", attrs: { for: box.id } }, box, "Keep open"));
}

async function keepOpen(assignment, box) {
  try {
    await api(`/api/assignments/${assignment.id}`, { method: "PATCH", json: { keep_open: box.checked } });
    say($("assignment-message"), box.checked ? `${assignment.name} keeps taking uploads beside your assignments.`
      : `${assignment.name} takes no more uploads once the course has assignments of yours.`, "success");
  } catch (error) {
    box.checked = !box.checked;
    say($("assignment-message"), `Not changed: ${error.message}`, "error");
  }
  await refresh();
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
