// The course's assignments: the list with their times (in the viewer's zone), creating one, publishing.

import { api } from "../api.js";
import { $, element, onClick, onSubmit, replaceKeepingFocus, say } from "../dom.js";
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
    const action = a.published_at ? element("span", { className: "muted", text: "published" })
      : element("button", { className: "secondary small", text: "Publish", attrs: { type: "button", "data-focus-key": `publish-${a.id}` } });
    if (!a.published_at) onClick(action, () => publish(a));
    return element("tr", {}, element("td", { text: a.name }), element("td", { text: zonedTime(a.opens_at) }),
      element("td", { text: zonedTime(a.due_at) }), element("td", { text: zonedTime(a.late_until) }),
      element("td", { text: String(a.seed) }), element("td", { text: String(a.private_seed ?? "–") }),
      element("td", { text: zonedTime(a.published_at) }), element("td", {}, action));
  }));
}

async function publish(assignment) {
  try {
    await api(`/api/assignments/${assignment.id}/publish`, { method: "POST" });
    say($("assignment-message"), `Published ${assignment.name}: the students see the private board.`, "success");
    await refresh();
  } catch (error) {
    say($("assignment-message"), `Not published: ${error.message}`, "error");
  }
}
