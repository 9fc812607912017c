// My submissions (/submissions): upload a model, watch its status change live, read why it
// failed, see its evaluation chart, select the final submission of each assignment (then see its
// private result and grade), pick the championship's active submission, start a friendly race.

import { api } from "../api.js";
import { $, badge, element, focusOn, onSubmit, replaceKeepingFocus, say } from "../dom.js";
import { showEpisodeChart } from "../episode-chart.js";
import { count, dateTime, number, outcomeText, uploadTimeLeft, zonedTime } from "../format.js";
import { Poller } from "../poller.js";
import { requireUser, showAccount } from "../session.js";
import { DONE, ENDED, FAILED, QUEUED, READY, REJECTED, RUNNING, VALIDATED } from "../statuses.js";
import { dropZone } from "../upload-zone.js";

const FAST_POLL_MS = 1000; // while something is being validated or evaluated
const SLOW_POLL_MS = 10000; // otherwise (e.g. an instructor re-runs evaluations)
const BASELINES_OWNER = "baselines";
const MB = 1024 * 1024; // as the server counts them

let me = null;
let submissions = [];
let selectedId = Number(new URLSearchParams(location.search).get("id")) || null;
let shownEvaluation = null; // "id:status" of the evaluation whose chart is drawn
let chosenFile = null;
let lastUpload = null; // {id, filename, validated}: its outcomes replace the "uploaded" message
let focusDetailOf = null; // the submission whose details take the focus once shown (after an upload or a pick)
let quotaKey = null; // the submissions' ids and statuses when the quota was last read

/** Validated and, when ready, evaluated (or the evaluation failed): nothing more will change. */
function settled(submission) {
  if (!VALIDATED.includes(submission.status)) return false;
  if (submission.status !== READY) return true;
  return ENDED.includes(submission.evaluation?.status);
}

// --------------------------------------------------------------------------- the list

async function refresh() {
  submissions = await api("/api/submissions");
  await Promise.all([refreshQuota(), refreshAssignments()]);
  renderList();
  reportUpload();
  fillRaceAgents();
  if (!selectedId && submissions.length) selectedId = submissions[0].id;
  if (selectedId) {
    try {
      await refreshDetail();
    } catch (error) {
      say($("page-message"), `Submission ${selectedId}: ${error.message}`, "error");
      selectedId = null;
      $("detail").hidden = true;
    }
  }
  poller.interval = submissions.every(settled) ? SLOW_POLL_MS : FAST_POLL_MS;
}

// --------------------------------------------------------------------------- assignments

async function refreshAssignments() {
  const assignments = await api("/api/assignments");
  const picker = $("upload-assignment");
  const open = assignments.filter((a) => a.state === "open" || a.state === "late");
  const kept = picker.value;
  // several open: the student picks one (never a silent first choice); one open: the server takes it
  picker.replaceChildren(element("option", { text: "Choose the assignment…", attrs: { value: "" } }),
    ...open.map((a) => element("option", { text: `${a.name}${a.state === "late" ? " (late)" : ""}`,
      attrs: { value: a.id } })));
  picker.value = open.some((a) => String(a.id) === kept) ? kept : "";
  picker.closest(".field").hidden = open.length < 2;
  const grades = await Promise.all(assignments.map(myGrade));
  replaceKeepingFocus($("assignments").tBodies[0], ...assignments.map((a, k) => element("tr", {},
    element("td", { text: a.name, attrs: { title: a.description || "" } }), element("td", {}, badge(a.state)),
    element("td", { text: zonedTime(a.opens_at) }),
    element("td", { text: zonedTime(a.my_due_at) + (a.extended ? " (extension)" : "") }),
    element("td", { text: uploadTimeLeft(a) }), element("td", { text: zonedTime(a.late_until) }),
    element("td", {}, finalCell(a)), element("td", { text: privateResult(a, grades[k]) }))));
}

/** The submission's name as this page lists it (the final one is always the student's own). */
function nameOf(id) {
  return submissions.find((s) => s.id === id)?.name || `#${id}`;
}

const choices = new Map(); // assignment id -> the option picked in its menu, kept across the polls' redraws

/** The student's final submission of an assignment and, until it is frozen, a menu to select another. */
function finalCell(a) {
  const final = a.final || {};
  const text = !final.submission_id ? "none yet"
    : final.selected ? `${nameOf(final.submission_id)} (selected)` : `best on the public board: ${nameOf(final.submission_id)}`;
  // frozen at the close time, decided once every upload made before it is validated and evaluated
  const state = !final.frozen_at ? "" : final.decided ? ", frozen" : ", frozen: decided once your uploads are evaluated";
  const cell = element("div", {}, element("span", { text: text + state }));
  const ready = submissions.filter((s) => s.assignment_id === a.id && s.status === READY);
  if (final.frozen_at || !["open", "late"].includes(a.state) || !ready.length) return cell;
  const menu = element("select", { attrs: { id: `final-${a.id}`, "aria-label": `Final submission of ${a.name}`,
                                            "data-focus-key": `final-${a.id}` } },
    element("option", { text: "my best on the public board", attrs: { value: "" } }),
    ...ready.map((s) => element("option", { text: `${s.name} (#${s.id})`, attrs: { value: s.id } })));
  menu.value = choices.get(a.id) ?? (final.selected ? String(final.submission_id) : "");
  menu.addEventListener("change", () => choices.set(a.id, menu.value));
  const button = element("button", { className: "secondary small", text: "Select",
    attrs: { type: "button", "aria-label": `Select: the final submission of ${a.name}`, "data-focus-key": `select-${a.id}` } });
  button.addEventListener("click", () => selectFinal(a, menu.value));
  cell.append(element("span", { className: "row" }, menu, button));
  return cell;
}

async function selectFinal(a, value) {
  const submissionId = value ? Number(value) : null;
  try {
    await api(`/api/assignments/${a.id}/selection`, { method: "POST", json: { submission_id: submissionId } });
    choices.delete(a.id);
    say($("assignment-message"), submissionId ? `${nameOf(submissionId)} is your final submission of ${a.name}.`
      : `Your best on the public board is your final submission of ${a.name}.`, "success");
    await poller.poll();
  } catch (error) {
    say($("assignment-message"), `Not selected: ${error.message}`, "error");
  }
}

const gradeCache = new Map(); // "id:published:rubric" -> the grade, or null (not published, no rubric)

/** The student's grade once the assignment is published (403/404/409 before: none, nothing shown). */
async function myGrade(a) {
  if (!a.published_at) return null;
  const key = `${a.id}:${a.published_at}:${JSON.stringify(a.rubric)}`;
  if (!gradeCache.has(key)) {
    gradeCache.set(key, await api(`/api/assignments/${a.id}/grades/me`).catch(() => null));
  }
  return gradeCache.get(key);
}

function privateResult(a, grade) {
  if (!a.published_at) return "after publication";
  const evaluation = a.final?.evaluation;
  const result = evaluation?.status === DONE
    ? `${evaluation.completed}/${evaluation.episodes_total} laps, return ${number(evaluation.mean_return, 2)}` : "–";
  if (!grade || grade.points === null) return result;
  const rank = grade.rank ? `, rank ${grade.rank} of ${grade.students}` : "";
  return `${result}; grade ${number(grade.points, 1)} of ${number(grade.max_points, 1)}${rank}${grade.late ? " (late)" : ""}`;
}

/** Uploads left today: read again when a submission comes or changes status (a rejected one is free). */
async function refreshQuota() {
  const key = submissions.map((s) => `${s.id}:${s.status}`).join();
  if (key === quotaKey) return;
  quotaKey = key;
  const quota = (await api("/api/users/me")).upload_quota;
  if (!quota) {
    $("upload-quota").textContent = "";
    return;
  }
  const next = quota.next_free_at ? `; the next one frees up at ${dateTime(quota.next_free_at)}` : "";
  $("upload-quota").textContent = `${quota.remaining} of ${count(quota.limit, "upload")} left in the last 24 hours ` +
    `(rejected uploads do not count)${next}.`;
}

function renderList() {
  const body = $("submissions").tBodies[0];
  if (!submissions.length) {
    body.replaceChildren(element("tr", {}, element("td", { className: "muted", text: "No submissions yet: upload your first agent above.", attrs: { colspan: 7 } })));
    return;
  }
  replaceKeepingFocus(body, ...submissions.map((s) => {
    const evaluation = s.evaluation;
    const done = evaluation?.status === DONE;
    const open = element("button", { className: "secondary small", text: s.name,
      attrs: { type: "button", "aria-label": `Show ${s.name}`, "aria-controls": "detail", "data-focus-key": `show-${s.id}` } });
    open.addEventListener("click", () => select(s.id));
    const row = element("tr", { attrs: { "data-id": s.id, "data-status": s.status } },
      element("td", {}, open),
      element("td", {}, statusBadges(s)),
      element("td", { text: dateTime(s.created_at) }),
      element("td", { className: "num", text: done ? `${evaluation.completed}/${evaluation.episodes_total}` : "–" }),
      element("td", { className: "num", text: done ? number(evaluation.mean_return) : "–" }),
      element("td", { className: "num", text: done ? number(evaluation.mean_speed, 3) : "–" }),
      element("td", {}, championshipCell(s)));
    if (s.id === selectedId) row.classList.add("selected");
    return row;
  }));
}

function statusBadges(s) {
  const cell = element("span", { className: "row" }, badge(s.status));
  const evaluation = s.evaluation?.status;
  if (s.status === READY && evaluation !== DONE) {
    cell.append(badge(evaluation === FAILED ? FAILED : RUNNING, evaluation === FAILED ? "evaluation failed" : "evaluating"));
  }
  if (s.evaluation?.stale) cell.append(badge("stale"));
  if (s.late) cell.append(badge("late"));
  return cell;
}

function championshipCell(s) {
  const cell = element("span", { className: "row" });
  if (s.active) cell.append(badge("active"));
  else if (s.status === READY) {
    const use = element("button", { className: "secondary small", text: "Make active",
      attrs: { type: "button", "aria-label": `Make active: ${s.name} races in championships`,
               "data-focus-key": `active-${s.id}`, "data-focus-next": `show-${s.id}` } }); // gone once it is
    use.addEventListener("click", () => update(s, { active: true }));
    cell.append(use);
  }
  if ("public" in s && s.status === READY) {
    const box = element("input", { attrs: { type: "checkbox", checked: s.public, "data-focus-key": `public-${s.id}` } });
    box.addEventListener("change", () => update(s, { public: box.checked }));
    cell.append(element("label", { className: "checks small" }, box, "public opponent"));
  }
  return cell;
}

async function update(s, change) {
  try {
    await api(`/api/submissions/${s.id}`, { method: "PATCH", json: change });
    say($("page-message"), "");
    await poller.poll();
  } catch (error) {
    say($("page-message"), `Could not change ${s.name}: ${error.message}`, "error");
  }
}

function select(id) {
  selectedId = id;
  const url = new URL(location.href);
  url.searchParams.set("id", id);
  history.replaceState(null, "", url);
  focusDetailOf = id;
  renderList();
  refreshDetail();
}

// --------------------------------------------------------------------------- one submission

async function refreshDetail() {
  const s = await api(`/api/submissions/${selectedId}`);
  $("detail").hidden = false;
  $("detail-title").replaceChildren(`${s.name} `, badge(s.status), ...(s.late ? [" ", badge("late")] : []));
  $("detail-facts").textContent = [s.filename, s.kind, `${(s.size / 1024).toFixed(1)} KB`, `sha256 ${s.sha256.slice(0, 12)}…`,
    s.obs_dim ? `observation size ${s.obs_dim}` : null,
    `uploaded ${dateTime(s.created_at)}${s.late ? " (late: after your due time)" : ""}`].filter(Boolean).join(" · ");
  say($("detail-error"), s.error ? `${s.status === REJECTED ? "Rejected" : "Failed"}: ${s.error}` : "", "error");
  showLog("validation-log", s.log);
  if (focusDetailOf === s.id) {
    focusDetailOf = null;
    focusOn($("detail-title"));
  }
  await renderEvaluation(s);
}

function showLog(id, text) {
  $(id).textContent = text || "";
  $(`${id}-box`).hidden = !text;
}

async function renderEvaluation(s) {
  const evaluation = s.evaluation;
  $("evaluation").hidden = s.status !== READY;
  showLog("evaluation-log", evaluation?.log);
  say($("evaluation-error"), evaluation?.status === FAILED ? `The evaluation failed: ${evaluation.error}` : "", "error");
  if (!evaluation || evaluation.status !== DONE) {
    $("evaluation-summary").replaceChildren(evaluation ? badge(evaluation.status) : badge(QUEUED),
      evaluation?.status === FAILED ? "" : " The evaluation runs as soon as a worker is free; this page updates by itself.");
    if (evaluation) showProvenance(evaluation);
    else $("evaluation-provenance").textContent = "";
    $("chart-box").hidden = true;
    shownEvaluation = null;
    return;
  }
  const settings = evaluation.settings || {};
  const options = Object.entries(settings.env_options || {}).map(([k, v]) => `${k}=${v}`).join(", ");
  $("evaluation-summary").textContent = `Completed ${evaluation.completed} of ${evaluation.episodes_total} laps · ` +
    `mean return ${number(evaluation.mean_return)} · mean speed ${number(evaluation.mean_speed, 3)} · ` +
    `mean steps ${number(evaluation.mean_steps, 0)} (seed ${settings.seed}${options ? `, ${options}` : ""}).`;
  showProvenance(evaluation);
  const key = `${evaluation.id}:${evaluation.status}`;
  if (key === shownEvaluation) return; // already drawn: no flicker on every poll
  const episodes = await allEpisodes(s.links.episodes, evaluation.episodes_total);
  if (s.id !== selectedId) return; // another submission was picked meanwhile
  shownEvaluation = key;
  $("chart-box").hidden = false;
  showEpisodeChart($("episode-chart"), $("chart-legend"), episodes);
  $("episodes").tBodies[0].replaceChildren(...episodes.map((e) => element("tr", {},
    element("td", { className: "num", text: e.index + 1 }), element("td", { className: "num", text: e.seed }),
    element("td", { className: "num", text: e.steps }), element("td", { className: "num", text: number(e.return) }),
    element("td", { className: "num", text: number(e.mean_speed, 3) }),
    element("td", { text: e.reason && e.outcome === "dnf" ? `${outcomeText(e.outcome)}: ${e.reason}` : outcomeText(e.outcome) }))));
}

/** What produced the result, as `league evaluate` prints it: compare the result keys. */
function showProvenance(evaluation) {
  const versions = evaluation.versions;
  $("evaluation-provenance").textContent = (versions ? `Simulator: physics ${versions.physics}, track format ` +
    `${versions.track_format} (league ${versions.package}) · ` : "") + `result key ${evaluation.result_key}` +
    (evaluation.stale ? " · stale: evaluated with other settings than the course's current ones, so it does not " +
      "rank until it is evaluated again." : "");
}

/** The episodes behind a status answer's link (it carries none), fetched once per evaluation. */
async function allEpisodes(link, total) {
  const url = new URL(link, location.origin);
  const episodes = [];
  while (episodes.length < total) {
    url.searchParams.set("offset", episodes.length);
    url.searchParams.set("limit", 1000);
    const page = await api(url.pathname + url.search);
    if (!page.items.length) break;
    episodes.push(...page.items);
  }
  return episodes;
}

// --------------------------------------------------------------------------- upload

/** Say (in the upload's status box, read out politely) how the last upload's validation, then its evaluation, ended. */
function reportUpload() {
  const s = lastUpload && submissions.find((item) => item.id === lastUpload.id);
  if (!s || !VALIDATED.includes(s.status)) return;
  const { filename } = lastUpload;
  const late = s.late ? " It was uploaded late (after your due time): the late penalty applies if it is your final." : "";
  if (s.status !== READY) {
    say($("upload-message"), `${filename} was ${s.status}: ${s.error}`, "error");
    lastUpload = null;
  } else if (!lastUpload.validated) {
    say($("upload-message"), `${filename} passed validation: it is ready and being evaluated.${late}`, "success");
    lastUpload.validated = true;
  }
  const evaluation = s.evaluation;
  if (s.status !== READY || !ENDED.includes(evaluation?.status)) return;
  say($("upload-message"), evaluation.status === DONE
    ? `${filename} is evaluated: ${evaluation.completed} of ${count(evaluation.episodes_total, "lap")} completed, ` +
      `mean return ${number(evaluation.mean_return)}.${late}`
    : `${filename} passed validation, but its evaluation failed: ${evaluation.error}`, evaluation.status === DONE ? "success" : "error");
  lastUpload = null;
}

dropZone($("drop-zone"), $("model-file"), (file) => {
  chosenFile = file;
  $("chosen-file").textContent = `Chosen: ${file.name} (${(file.size / 1024).toFixed(1)} KB)`;
});

onSubmit($("upload-form"), async () => {
  const message = $("upload-message");
  if (!chosenFile) {
    say(message, "Choose a model file first (drop it on the box or click the box).", "error");
    return;
  }
  if (chosenFile.size > Number($("drop-zone").dataset.maxBytes)) { // the server's limit, in the page
    say(message, `${chosenFile.name} is ${(chosenFile.size / MB).toFixed(1)} MB, over the ${$("upload-limit").textContent} ` +
      "limit: upload a smaller model file.", "error");
    return;
  }
  const picking = !$("upload-assignment").closest(".field").hidden;
  if (picking && !$("upload-assignment").value) {
    const names = [...$("upload-assignment").options].filter((o) => o.value).map((o) => o.text);
    say(message, `Several assignments are open (${names.join(", ")}): choose the one this upload is for.`, "error");
    $("upload-assignment").focus();
    return;
  }
  const form = new FormData();
  form.append("file", chosenFile, chosenFile.name);
  const name = $("submission-name").value.trim();
  if (name) form.append("name", name);
  if (picking) form.append("assignment", $("upload-assignment").value);
  $("upload-button").disabled = true;
  say(message, `Uploading ${chosenFile.name}…`, "info");
  try {
    const created = await api("/api/submissions", { method: "POST", form });
    say(message, `Uploaded ${chosenFile.name}: it is ${created.status}; it will be validated, then evaluated.`, "success");
    selectedId = created.id;
    focusDetailOf = created.id;
    lastUpload = { id: created.id, filename: chosenFile.name, validated: false };
    shownEvaluation = null;
    chosenFile = null;
    const picked = $("upload-assignment").value; // the student's choice stays, shown, for their next upload
    $("upload-form").reset();
    $("upload-assignment").value = picked;
    $("chosen-file").textContent = "";
    await poller.poll();
  } catch (error) {
    say(message, `Upload refused: ${error.message}`, "error");
  }
  $("upload-button").disabled = false;
  // uploaded, the new submission's details take the focus; refused, the button gets back the focus it lost while disabled
  if (focusDetailOf === null && document.activeElement === document.body) $("upload-button").focus();
});

// --------------------------------------------------------------------------- friendly race

function fillRaceAgents() {
  const select = $("race-agent");
  const ready = submissions.filter((s) => s.status === READY);
  const previous = select.value;
  select.replaceChildren(...ready.map((s) => element("option", { text: `${s.name} (#${s.id})`, attrs: { value: s.id } })));
  if (ready.some((s) => String(s.id) === previous)) select.value = previous;
  $("race-button").disabled = !ready.length;
}

async function loadOpponents() {
  const box = $("opponents");
  try {
    const page = await api("/api/leaderboard?page=1&size=100");
    // other students' agents can be raced once their owners make them public; the baselines always
    const others = page.items.filter((row) => row.owner !== me.name && (row.public || row.owner === BASELINES_OWNER));
    if (!others.length) {
      box.replaceChildren(element("span", { className: "muted", text: "No opponents yet." }));
      return;
    }
    box.replaceChildren(...others.map((row) => element("label", {},
      element("input", { attrs: { type: "checkbox", name: "opponent", value: row.submission_id, checked: row.owner === BASELINES_OWNER } }),
      `${row.name} (${row.owner})`)));
  } catch (error) {
    box.replaceChildren(element("span", { className: "muted", text: `Opponents could not be loaded: ${error.message}` }));
  }
}

onSubmit($("race-form"), async () => {
  const message = $("race-message");
  const mine = Number($("race-agent").value);
  const opponents = [...document.querySelectorAll("input[name=opponent]:checked")].map((box) => Number(box.value));
  if (!mine) {
    say(message, "You need a ready submission to race.", "error");
    return;
  }
  try {
    const race = await api("/api/races", { method: "POST", json: { submission_ids: [mine, ...opponents] } });
    message.className = "message success";
    message.replaceChildren(`Race ${race.id} started (${race.status}). `,
      element("a", { text: "Watch the race", attrs: { href: `/races/${race.id}` } }));
  } catch (error) {
    say(message, `The race could not start: ${error.message}`, "error");
  }
});

// --------------------------------------------------------------------------- display name

const VISIBILITY_TEXT = {
  public: "Your course's boards are public: visitors see your display name (or a pseudonym), members your name.",
  members: "Your course's boards are shown to its students and instructors only, with names; " +
    "a display name is shown if your instructor makes them public.",
  instructors: "Your course's boards are shown to its instructors only; you see your own races and results here.",
};

async function setUpDisplayName() {
  $("display-name").value = me.display_name || "";
  try {
    const { board_visibility: visibility } = await api("/api/settings/privacy");
    $("display-note").textContent = VISIBILITY_TEXT[visibility] || $("display-note").textContent;
  } catch {
    // the note's general text stays
  }
  onSubmit($("display-form"), async () => {
    try {
      me = await api("/api/users/me", { method: "PATCH", json: { display_name: $("display-name").value } });
      $("display-name").value = me.display_name || "";
      say($("display-message"), me.display_name ? `Saved: visitors of public boards see "${me.display_name}".`
        : "Saved: visitors of public boards see a pseudonym.", "success");
    } catch (error) {
      say($("display-message"), `Not saved: ${error.message}`, "error");
    }
  });
}

// --------------------------------------------------------------------------- start

const poller = new Poller(refresh, FAST_POLL_MS);

async function start() {
  try {
    me = await requireUser();
  } catch (error) {
    say($("page-message"), error.message, "error");
    return;
  }
  showAccount(me);
  setUpDisplayName();
  await poller.poll();
  loadOpponents();
}

start();
