// Championships: create one, run a round and watch its heats finish (said in the status box, which
// screen readers read out politely), open the races' replays. After creating a championship the
// focus goes to its card's heading, after running a round to the round's line.

import { api } from "../api.js";
import { $, badge, element, focusOn, onSubmit, replaceKeepingFocus, say } from "../dom.js";
import { count } from "../format.js";
import { Poller } from "../poller.js";
import { DONE, FAILED, PENDING, RUNNING } from "../statuses.js";
import { EnvOptionsFields, describeOptions } from "./env-options.js";

const ROUND_POLL_MS = 1000;
const watched = new Map(); // "championship/round" -> Poller

export async function setUpChampionships() {
  const options = new EnvOptionsFields($("champ-options"), "champ");
  $("new-championship").addEventListener("toggle", () => $("new-championship").open && fillAssignments());
  onSubmit($("championship-form"), async () => {
    let created;
    try {
      created = await api("/api/championships", { method: "POST", json: championshipBody(options) });
    } catch (error) {
      say($("championships-message"), `Not created: ${error.message}`, "error");
      return;
    }
    $("championship-form").reset();
    $("new-championship").open = false;
    say($("championships-message"), `Created the championship “${created.name}”.`, "success");
    try { // created whatever the list says next: a failure here must not read as "not created" (and a second click)
      await refreshChampionships();
      focusOn(document.querySelector(`[data-focus-key="championship-${created.id}"]`));
    } catch (error) {
      say($("championships-message"), `Created the championship “${created.name}”, but the list could not be ` +
        `read again: ${error.message}`, "error");
    }
  });
  await refreshChampionships();
}

function championshipBody(options) {
  const points = $("champ-points").value.split(/[,\s]+/).filter(Boolean).map(Number);
  const body = {
    name: $("champ-name").value.trim(),
    heat_size: Number($("champ-heat").value),
    points,
    include_baselines: $("champ-baselines").checked,
    env_options: options.read(),
  };
  if ($("champ-seed").value.trim() !== "") body.seed = Number($("champ-seed").value);
  if ($("champ-assignment").value) body.assignment = Number($("champ-assignment").value);
  return body;
}

/** The assignment menu, read again whenever the form opens (one may have been created meanwhile). */
async function fillAssignments() {
  const menu = $("champ-assignment");
  const kept = menu.value;
  try {
    const assignments = await api("/api/assignments");
    menu.replaceChildren(element("option", { text: "none", attrs: { value: "" } }),
      ...assignments.map((a) => element("option", { text: a.name, attrs: { value: a.id } })));
    menu.value = assignments.some((a) => String(a.id) === kept) ? kept : "";
  } catch (error) {
    say($("championships-message"), `The assignments could not be read: ${error.message}`, "error");
  }
}

async function refreshChampionships() {
  const list = await api("/api/championships");
  const championships = Array.isArray(list) ? list : list.items || [];
  if (!championships.length) {
    $("championships").replaceChildren(element("p", { className: "muted", text: "No championship yet: create one above." }));
    return;
  }
  const details = await Promise.all(championships.map((c) => api(`/api/championships/${c.id}`)));
  replaceKeepingFocus($("championships"), ...details.sort((a, b) => b.id - a.id).map(championshipCard));
  for (const championship of details) {
    for (const round of championship.rounds || []) {
      if (round.status === PENDING || round.status === RUNNING) watchRound(championship.id, round.number);
    }
  }
}

function championshipCard(championship) {
  const rounds = championship.rounds || [];
  const run = element("button", { text: `Run round ${rounds.length + 1}`, attrs: { type: "button", "data-focus-key": `run-${championship.id}` } });
  run.addEventListener("click", () => runRound(championship, run));
  const facts = [`${championship.heat_size} cars per heat`, `points ${(championship.points || []).join("-")}`,
    championship.include_baselines ? "baselines take part" : "students only",
    championship.assignment_id ? `final submissions of assignment ${championship.assignment_id}` : null,
    describeOptions(championship.env_options),
    championship.seed !== null && championship.seed !== undefined ? `heats drawn with seed ${championship.seed}` : null].filter(Boolean);
  return element("article", { className: "panel", attrs: { "data-championship": championship.id, "aria-label": championship.name } },
    element("div", { className: "row" },
      element("h3", { text: championship.name, attrs: { tabindex: "-1", "data-focus-key": `championship-${championship.id}` } }), run,
      element("a", { text: "Standings", attrs: { href: `/?championship=${championship.id}`, "data-focus-key": `standings-${championship.id}` } })),
    element("p", { className: "small muted", text: facts.join(" · ") }),
    element("ol", { className: "rounds", attrs: { "aria-label": `Rounds of ${championship.name}` } },
      ...(rounds.length ? rounds.map((round) => roundItem(championship.id, round))
        : [element("li", { className: "muted", text: "No round yet." })])));
}

function roundItem(championshipId, round) {
  const item = element("li", { attrs: { "data-round": round.number, tabindex: "-1", "data-focus-key": `round-${championshipId}-${round.number}` } });
  fillRound(item, round);
  return item;
}

function fillRound(item, round) {
  const total = round.heats_total || 0;
  const progress = element("progress", { attrs: { max: Math.max(total, 1), value: round.heats_done || 0,
    "aria-label": `Round ${round.number}: ${round.heats_done} of ${total} heats done` } });
  const links = (round.race_ids || []).map((raceId, i) => element("a", { text: `Heat ${i + 1}`,
    attrs: { href: `/races/${raceId}`, "data-focus-key": `race-${raceId}` } }));
  replaceKeepingFocus(item, element("div", { className: "row" }, element("strong", { text: `Round ${round.number}` }), badge(round.status),
    element("span", { text: `${round.heats_done ?? 0}/${total} heats done` }), ...links.flatMap((link) => [link])), progress);
}

async function runRound(championship, button) {
  button.disabled = true;
  let round;
  try {
    round = await api(`/api/championships/${championship.id}/rounds`, { method: "POST" });
  } catch (error) {
    say($("championships-message"), `The round did not start: ${error.message}`, "error");
    button.disabled = false;
    button.focus(); // it lost the focus while disabled
    return;
  }
  say($("championships-message"), `Round ${round.number} of ${championship.name} started: ` +
    `${count(round.heats_total, "heat")} to race.`, "success");
  watchRound(championship.id, round.number, championship.name); // before the refresh watches it unnamed
  try {
    await refreshChampionships();
    focusOn(document.querySelector(`[data-focus-key="round-${championship.id}-${round.number}"]`));
  } catch (error) { // started all the same: the watch above says how it goes
    say($("championships-message"), `Round ${round.number} started, but the championships could not be read ` +
      `again: ${error.message}`, "error");
  }
}

/**
 * Poll a running round until it is done (or failed), updating its line of the card. A round this
 * page started (`name` given) has its progress and its end said in the status box.
 */
function watchRound(championshipId, number, name = null) {
  const key = `${championshipId}/${number}`;
  if (watched.has(key)) return;
  let said = 0; // heats done when last said
  const poller = new Poller(async () => {
    const round = await api(`/api/championships/${championshipId}/rounds/${number}`);
    const item = document.querySelector(`[data-championship="${championshipId}"] [data-round="${number}"]`);
    if (item) fillRound(item, round);
    if (name && (round.heats_done !== said || round.status === DONE || round.status === FAILED)) {
      said = round.heats_done;
      sayProgress(name, round);
    }
    if (round.status === DONE || round.status === FAILED) {
      watched.delete(key);
      await refreshChampionships();
      return false;
    }
    return true;
  }, ROUND_POLL_MS);
  watched.set(key, poller);
  poller.poll();
}

function sayProgress(name, round) {
  const heats = `${round.heats_done} of ${count(round.heats_total, "heat")} done`;
  if (round.status === DONE) {
    say($("championships-message"), `Round ${round.number} of ${name} is over: ${heats}; the standings are updated.`, "success");
  } else if (round.status === FAILED) {
    say($("championships-message"), `Round ${round.number} of ${name} failed: ${heats}. The Jobs table says why.`, "error");
  } else {
    say($("championships-message"), `Round ${round.number} of ${name}: ${heats}.`, "info");
  }
}
