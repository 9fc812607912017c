// The course's evaluation settings, every submission of the course, and re-running evaluations.

import { api } from "../api.js";
import { $, badge, element, onClick, onSubmit, replaceKeepingFocus, say } from "../dom.js";
import { count, number } from "../format.js";
import { Poller } from "../poller.js";
import { DONE, ENDED, FAILED, PENDING, READY, VALIDATING } from "../statuses.js";
import { EnvOptionsFields, describeOptions } from "./env-options.js";

const FAST_POLL_MS = 2000;
const SLOW_POLL_MS = 15000;

export async function setUpEvaluations() {
  const options = new EnvOptionsFields($("eval-options"), "eval");
  let saved = await api("/api/settings/evaluation");
  showSettings(saved, options);

  onSubmit($("settings-form"), async () => {
    const body = { seed: Number($("eval-seed").value), episodes: Number($("eval-episodes").value), env_options: options.read() };
    try {
      saved = await api("/api/settings/evaluation", { method: "PUT", json: body });
      showSettings(saved, options);
      const again = saved.reevaluating.length;
      say($("settings-message"), `Saved. ${again ? `${count(again, "submission")} will be evaluated again with these ` +
        "settings, after the students' own uploads; until then their results show as stale." : "No submission needs " +
        "evaluating again: each has a result of these settings."}`, "success");
      submissionsPoller.poll();
    } catch (error) {
      say($("settings-message"), `Not saved: ${error.message}`, "error");
    }
  });

  const submissionsPoller = new Poller(refreshSubmissions, SLOW_POLL_MS);
  setUpRerunAll(() => saved, submissionsPoller);
  await submissionsPoller.poll();

  async function refreshSubmissions() {
    const submissions = await api("/api/submissions?all=true");
    replaceKeepingFocus($("all-submissions").tBodies[0], ...submissions.map((s) => submissionRow(s, submissionsPoller)));
    const busy = submissions.some((s) => [PENDING, VALIDATING].includes(s.status) ||
      (s.status === READY && !ENDED.includes(s.evaluation?.status)));
    submissionsPoller.interval = busy ? FAST_POLL_MS : SLOW_POLL_MS;
  }
}

/** "Re-run every evaluation", once the dialog that asks first is confirmed. */
function setUpRerunAll(savedSettings, submissionsPoller) {
  onClick($("rerun-all"), () => askToRerunAll(savedSettings()).catch((error) => say($("settings-message"), error.message, "error")));
  onClick($("rerun-cancel"), () => $("rerun-dialog").close());
  onClick($("rerun-confirm"), async () => {
    $("rerun-dialog").close();
    try {
      const { queued } = await api("/api/evaluations/rerun", { method: "POST", json: { all: true } });
      say($("settings-message"), `Queued ${count(queued.length, "evaluation")} with the current settings.`, "success");
      submissionsPoller.poll();
    } catch (error) {
      say($("settings-message"), `Nothing re-run: ${error.message}`, "error");
    }
  });
}

/** Re-running the whole course queues a job per submission: say how many, and with what, first. */
async function askToRerunAll(settings) {
  const ready = (await api("/api/submissions?all=true")).filter((s) => s.status === READY).length;
  if (!ready) {
    say($("settings-message"), "There is no ready submission to evaluate again.", "info");
    return;
  }
  $("rerun-summary").textContent = `This evaluates the ${count(ready, "ready submission")} of the course again (the ` +
    `baselines' too), with the saved settings: seed ${settings.seed}, ${count(settings.episodes, "episode")}, ` +
    `${describeOptions(settings.env_options)}. That is ${count(ready, "job")} for the workers.`;
  $("rerun-confirm").textContent = `Re-run ${count(ready, "evaluation")}`;
  $("rerun-dialog").showModal();
}

function showSettings(settings, options) {
  $("eval-seed").value = settings.seed;
  $("eval-episodes").value = settings.episodes;
  options.show(settings.env_options);
}

function submissionRow(s, poller) {
  const evaluation = s.evaluation;
  const done = evaluation?.status === DONE;
  const actions = element("span", { className: "row" });
  if (s.status === READY) {
    const rerun = element("button", { className: "secondary small", text: "Re-run",
      attrs: { type: "button", "aria-label": `Re-run the evaluation of ${s.name} (${s.owner})`, "data-focus-key": `rerun-${s.id}` } });
    rerun.addEventListener("click", async () => {
      try {
        await api("/api/evaluations/rerun", { method: "POST", json: { submission_id: s.id } });
        say($("submissions-message"), `Re-running the evaluation of ${s.name}.`, "success");
        poller.poll();
      } catch (error) {
        say($("submissions-message"), error.message, "error");
      }
    });
    actions.append(rerun);
  }
  return element("tr", { attrs: { "data-id": s.id } },
    element("td", { className: "num", text: s.id }), element("td", { text: s.owner }),
    element("td", { text: s.name, attrs: { title: s.filename } }),
    element("td", {}, badge(s.status), reason(s.error)),
    element("td", {}, ...(evaluation ? [badge(evaluation.status), evaluation.stale ? badge("stale") : null]
      : [element("span", { className: "muted", text: "–" })]),
      reason(evaluation?.status === FAILED ? evaluation.error : null)),
    element("td", { className: "num", text: done ? `${evaluation.completed}/${evaluation.episodes_total}` : "–" }),
    element("td", { className: "num", text: done ? number(evaluation.mean_return) : "–" }),
    element("td", {}, actions));
}

/** Why a submission was rejected or an evaluation failed, in the table itself (not only on hover). */
function reason(text) {
  return text ? element("span", { className: "reason", text }) : null;
}
