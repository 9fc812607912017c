// The course's evaluation settings, every submission of the course, and re-running evaluations.

import { api } from "../api.js";
import { badge, element, number, say } from "../format.js";
import { Poller } from "../poller.js";
import { EnvOptionsFields } from "./env-options.js";

const $ = (id) => document.getElementById(id);
const FAST_POLL_MS = 2000;
const SLOW_POLL_MS = 15000;

export async function setUpEvaluations() {
  const options = new EnvOptionsFields($("eval-options"), "eval");
  const settings = await api("/api/settings/evaluation");
  showSettings(settings, options);

  $("settings-form").addEventListener("submit", async (event) => {
    event.preventDefault();
    const body = { seed: Number($("eval-seed").value), episodes: Number($("eval-episodes").value), env_options: options.read() };
    try {
      showSettings(await api("/api/settings/evaluation", { method: "PUT", json: body }), options);
      say($("settings-message"), "Saved. New submissions are evaluated with these settings; re-run the others to update them.", "success");
    } catch (error) {
      say($("settings-message"), `Not saved: ${error.message}`, "error");
    }
  });

  $("rerun-all").addEventListener("click", async () => {
    try {
      const { queued } = await api("/api/evaluations/rerun", { method: "POST", json: { all: true } });
      say($("settings-message"), `Queued ${queued.length} evaluations with the current settings.`, "success");
      submissionsPoller.poll();
    } catch (error) {
      say($("settings-message"), `Nothing re-run: ${error.message}`, "error");
    }
  });

  const submissionsPoller = new Poller(refreshSubmissions, SLOW_POLL_MS);
  await submissionsPoller.poll();

  async function refreshSubmissions() {
    const submissions = await api("/api/submissions?all=true");
    $("all-submissions").tBodies[0].replaceChildren(...submissions.map((s) => submissionRow(s, submissionsPoller)));
    const busy = submissions.some((s) => ["pending", "validating"].includes(s.status) ||
      (s.status === "ready" && !["done", "failed"].includes(s.evaluation?.status)));
    submissionsPoller.interval = busy ? FAST_POLL_MS : SLOW_POLL_MS;
  }
}

function showSettings(settings, options) {
  $("eval-seed").value = settings.seed;
  $("eval-episodes").value = settings.episodes;
  options.show(settings.env_options);
}

function submissionRow(s, poller) {
  const evaluation = s.evaluation;
  const done = evaluation?.status === "done";
  const actions = element("span", { className: "row" });
  if (s.status === "ready") {
    const rerun = element("button", { className: "secondary small", text: "Re-run",
      attrs: { type: "button", "aria-label": `Re-run the evaluation of ${s.name} (${s.owner})` } });
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
    element("td", { text: s.name, attrs: { title: s.error || s.filename } }),
    element("td", {}, badge(s.status)),
    element("td", {}, evaluation ? badge(evaluation.status) : element("span", { className: "muted", text: "–" })),
    element("td", { className: "num", text: done ? `${evaluation.completed}/${evaluation.episodes_total}` : "–" }),
    element("td", { className: "num", text: done ? number(evaluation.mean_return) : "–" }),
    element("td", {}, actions));
}
