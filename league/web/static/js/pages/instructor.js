// The instructor console (/instructor): students, evaluation settings, assignments, championships, grades,
// jobs, the audit log.

import { api } from "../api.js";
import { $, badge, element, onClick, onSubmit, replaceKeepingFocus, say } from "../dom.js";
import { dateTime } from "../format.js";
import { setUpAssignments } from "../instructor/assignments.js";
import { setUpAudit } from "../instructor/audit.js";
import { setUpChampionships } from "../instructor/championships.js";
import { setUpEvaluations } from "../instructor/evaluations.js";
import { setUpGrades } from "../instructor/grades.js";
import { setUpStudents } from "../instructor/students.js";
import { Poller } from "../poller.js";
import { requireInstructor } from "../session.js";

const JOBS_POLL_MS = 5000;

/** What a job works on: a race (linked to its replay) or a submission. */
function jobSubject(job) {
  if (job.race_id) return element("a", { text: `race #${job.race_id}`, attrs: { href: `/races/${job.race_id}`, "data-focus-key": `job-${job.id}` } });
  return job.kind + (job.submission_id ? ` #${job.submission_id}` : "");
}

async function refreshJobs() {
  const jobs = await api("/api/jobs?limit=20");
  replaceKeepingFocus($("jobs").tBodies[0], ...jobs.map((job) => element("tr", {},
    element("td", { className: "num", text: job.id }),
    element("td", {}, jobSubject(job)),
    element("td", {}, badge(job.status)), element("td", { className: "num", text: job.attempts }),
    element("td", { text: job.worker_id || "–" }), element("td", { text: dateTime(job.created_at) }),
    element("td", { text: job.error || "" }))));
}

/** Who sees the course's boards (PUT /api/settings/privacy: the next request of every page follows it). */
async function setUpPrivacy() {
  $("board-visibility").value = (await api("/api/settings/privacy")).board_visibility;
  onSubmit($("privacy-form"), async () => {
    try {
      const saved = await api("/api/settings/privacy", { method: "PUT", json: { board_visibility: $("board-visibility").value } });
      $("board-visibility").value = saved.board_visibility;
      say($("privacy-message"), "Saved: the boards follow it from now on.", "success");
    } catch (error) {
      say($("privacy-message"), `Not saved: ${error.message}`, "error");
    }
  });
}

async function start() {
  const me = await requireInstructor();
  if (!me) return;
  const jobs = new Poller(refreshJobs, JOBS_POLL_MS);
  onClick($("refresh-jobs"), () => jobs.poll());
  const parts = [setUpStudents(me), setUpEvaluations(), setUpAssignments(), setUpPrivacy(), setUpChampionships(),
    setUpGrades(), jobs.poll(), setUpAudit()];
  const results = await Promise.allSettled(parts);
  const failures = results.filter((r) => "reason" in r).map((r) => r.reason.message); // the rejected parts
  if (failures.length) say($("page-message"), failures.join(" "), "error");
}

start();
