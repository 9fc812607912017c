// Grades: an assignment's rubric, its grades on the private tracks, and the files gradebooks import.

import { api, download } from "../api.js";
import { $, badge, element, onClick, onSubmit, replaceKeepingFocus, say } from "../dom.js";
import { number } from "../format.js";

// shown in an assignment without a rubric: a start to edit (the server README's Grades has more)
const EXAMPLE = {
  kind: "points", max_points: 10, completed: { kind: "linear", points: 6 }, rank: { kind: "linear", points: 4 },
};
// each status: its words, and the badge style it shares with the submissions' statuses
const STATUS = { graded: ["graded", "done"], "no final": ["no final (0)", "rejected"], open: ["not closed yet", "queued"],
  pending: ["evaluating", "running"], stale: ["stale: other settings", "pending"], reference: ["baseline", "reference"] };

export async function setUpGrades() {
  const assignments = await api("/api/assignments");
  const select = $("grades-assignment");
  const listAssignments = () => select.replaceChildren(
    ...assignments.map((a) => element("option", { text: a.name, attrs: { value: a.id } })));
  listAssignments();
  const current = () => assignments.find((a) => String(a.id) === select.value);
  select.addEventListener("change", () => show(current()));
  // an assignment created in the Assignments section meanwhile joins the list when the list is reached
  select.addEventListener("focus", async () => {
    const fresh = await api("/api/assignments");
    if (fresh.length === assignments.length) return;
    const chosen = select.value;
    assignments.splice(0, assignments.length, ...fresh);
    listAssignments();
    select.value = chosen;
  });

  onSubmit($("rubric-form"), async () => {
    const assignment = current();
    let rubric;
    try {
      rubric = JSON.parse($("rubric-text").value);
    } catch (error) {
      say($("grades-message"), `Not saved: the rubric is not JSON (${error.message}).`, "error");
      return;
    }
    try {
      const saved = await api(`/api/assignments/${assignment.id}/rubric`, { method: "PUT", json: rubric });
      assignments.splice(assignments.indexOf(assignment), 1, saved);
      say($("grades-message"), `Saved: ${saved.name} is graded with this rubric.`, "success");
      await show(saved, false);
    } catch (error) {
      say($("grades-message"), `Not saved: ${error.message}`, "error");
    }
  });
  const file = (query, name) => () => download(`/api/assignments/${current().id}/grades.csv${query}`,
    `${current().name}${name}.csv`).catch((error) => say($("grades-message"), error.message, "error"));
  onClick($("grades-csv"), file("", ""));
  onClick($("grades-canvas"), file("?format=canvas", " (Canvas)"));
  onClick($("grades-moodle"), file("?format=moodle", " (Moodle)"));
  onClick($("grades-course"), () => download("/api/grades.csv", "grades.csv")
    .catch((error) => say($("grades-message"), error.message, "error")));
  if (!assignments.length) return;
  select.value = assignments.at(-1).id; // the newest: the one being graded, most likely
  await show(current());
}

/** The assignment's rubric in the editor, and its grades (or why there are none). */
async function show(assignment, sayNothing = true) {
  $("rubric-text").value = JSON.stringify(assignment.rubric || EXAMPLE, null, 2);
  const body = $("grades").tBodies[0];
  $("grades-canvas-match").hidden = true;
  if (!assignment.rubric) {
    body.replaceChildren();
    say($("grades-message"), `${assignment.name} has no rubric yet: edit the example above and save it.`, "info");
    return;
  }
  try {
    const grades = await api(`/api/assignments/${assignment.id}/grades`);
    replaceKeepingFocus(body, ...grades.rows.map((row) => gradeRow(row, grades.max_points)));
    if (sayNothing) say($("grades-message"), "");
    await showCanvasMatch(assignment);
  } catch (error) {
    body.replaceChildren();
    say($("grades-message"), error.message, "error");
  }
}

/** Before the Canvas file is downloaded: how many of its students carry an id Canvas matches them by. */
async function showCanvasMatch(assignment) {
  const match = await api(`/api/assignments/${assignment.id}/grades/canvas-match`);
  const box = $("grades-canvas-match");
  box.textContent = `For Canvas: ${match.summary}.` + (match.by_id.length < match.students
    ? " Import Canvas's own gradebook export as the roster to carry its ids." : "");
  box.hidden = false;
}

function gradeRow(row, maxPoints) {
  const reference = row.role === "baseline";
  return element("tr", { className: reference ? "muted" : undefined },
    element("td", { className: "num", text: row.rank ?? "–" }),
    element("td", { text: row.name }),
    element("td", {}, badge(STATUS[row.status][1], STATUS[row.status][0])),
    element("td", { className: "num", text: row.completed === null ? "–" : `${number(100 * row.completed, 1)} %` }),
    element("td", { className: "num", text: row.mean_speed === null ? "–" : number(row.mean_speed, 3) }),
    element("td", { text: row.late ? `late (×${row.penalty})` : "" }),
    element("td", { className: "num", text: row.points === null ? "–" : `${number(row.points)} / ${number(maxPoints)}` }),
    element("td", { text: row.revoked ? "revoked" : "" }));
}
