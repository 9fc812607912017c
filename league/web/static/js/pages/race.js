// The race viewer: /races/{id} plays a race stored on the server (waiting while it runs);
// /replay plays a replay file saved by `league race --replay`. ?step=N opens at step N.

import { api } from "../api.js";
import { $, badge, element, onClick, say } from "../dom.js";
import { dateTime, finalText, number } from "../format.js";
import { markerIcon } from "../palette.js";
import { Player } from "../player.js";
import { RacePainter } from "../race-painter.js";
import { Replay } from "../replay.js";
import { optionalUser, showAccount } from "../session.js";
import { FAILED, PENDING, RUNNING } from "../statuses.js";
import { dropZone } from "../upload-zone.js";

const RACE_POLL_MS = 1500;
const DEFAULT_SPEED = 2;
const raceId = (location.pathname.match(/^\/races\/([^/]+)$/) || [])[1];
const requestedStep = new URLSearchParams(location.search).get("step");

let viewer = null; // {replay, painter, player}

// --------------------------------------------------------------------------- loading

async function loadRace() {
  $("race-heading").textContent = `Race ${raceId}`;
  document.title = `Race ${raceId} · MicroRacer League`;
  let race;
  try {
    race = await raceWhenOver();
  } catch (error) {
    say($("race-message"), `Race ${raceId}: ${error.message}`, "error");
    return;
  }
  if (race.status === FAILED) {
    say($("race-message"), `This race failed: ${race.error || "no reason recorded"}`, "error");
    return;
  }
  const replay = await api(`/api/races/${encodeURIComponent(raceId)}/replay`, { loginOn401: false });
  await show(replay, race);
}

/**
 * The race once it is done or failed, and its replay shown (a championship heat's once every heat
 * of its round is over: the replay shows the round's track, secret until then); meanwhile, say why not yet.
 */
async function raceWhenOver() {
  for (;;) {
    const race = await api(`/api/races/${encodeURIComponent(raceId)}`, { loginOn401: false }); // the board's visibility decides
    const over = race.status !== PENDING && race.status !== RUNNING;
    const sealed = race.round !== null && race.seed === null;
    if (over && !sealed) return race;
    const names = (race.entrants || []).map((e) => e.name).join(", ");
    const wait = over ? ` This heat is ${race.status}; it plays here once every heat of round ${race.round} is over.`
      : ` The race is ${race.status}; it plays here when it is over.`;
    $("race-message").replaceChildren(badge(race.status), wait, names ? ` Cars: ${names}.` : "");
    await new Promise((resolve) => setTimeout(resolve, RACE_POLL_MS));
  }
}

function openReplayFile() {
  $("race-heading").textContent = "Replay";
  $("file-box").hidden = false;
  say($("race-message"), "");
  dropZone($("replay-drop"), $("replay-file"), async (file) => {
    try {
      const data = JSON.parse(await file.text());
      say($("file-message"), "");
      await show(data, null);
      $("race-heading").textContent = `Replay: ${file.name}`;
    } catch (error) {
      say($("file-message"), `${file.name} cannot be played: ${error.message}`, "error");
    }
  });
}

// --------------------------------------------------------------------------- the viewer

async function show(data, race) {
  const replay = new Replay(data);
  const geometry = data.geometry || await api("/api/tracks/geometry", { method: "POST", json: data.track, auth: false });
  if (viewer) {
    viewer.player.pause();
    viewer.painter.destroy();
  }
  $("viewer").hidden = false;
  say($("race-message"), "");
  const painter = new RacePainter($("race-canvas"), geometry, replay);
  const player = new Player({
    totalSteps: replay.totalSteps,
    stepsPerSecond: 1 / replay.tstep,
    onStep: (step) => render(step),
    onState: (playing) => {
      $("play-button").textContent = playing ? "Pause" : "Play";
      $("play-button").setAttribute("aria-pressed", String(playing));
      if (!playing) rememberStep();
    },
  });
  player.speed = Number($("speed").value) || DEFAULT_SPEED;
  viewer = { replay, painter, player };
  $("scrubber").max = String(replay.totalSteps);
  $("race-canvas").setAttribute("aria-label", canvasLabel(replay));
  buildLegend(replay);
  showClassification(replay, race);
  $("share-row").hidden = !raceId;
  $("play-button").focus({ preventScroll: true }); // Space and the arrows work at once
  const step = requestedStep === null ? 0 : Math.min(Math.max(Number(requestedStep) || 0, 0), replay.totalSteps);
  player.seek(step);
  const reducedMotion = window.matchMedia("(prefers-reduced-motion: reduce)").matches;
  if (requestedStep === null && !reducedMotion) player.play();
}

function render(step) {
  const { replay, painter } = viewer;
  painter.draw(step);
  $("scrubber").value = String(step);
  $("scrubber").setAttribute("aria-valuetext", `${replay.seconds(step).toFixed(1)} seconds, step ${step} of ${replay.totalSteps}`);
  $("clock").textContent = `t = ${replay.seconds(step).toFixed(1)} s · step ${step}/${replay.totalSteps}`;
  $("viewer").dataset.step = String(step);
  if (raceId) $("share-link").value = linkToStep(step);
  document.querySelectorAll("#car-legend .car-status").forEach((line, i) => {
    const { text, final } = replay.legend(i, step);
    line.textContent = text;
    line.classList.toggle("final", final);
  });
}

function buildLegend(replay) {
  $("car-legend").replaceChildren(...replay.names.map((name, i) => element("li", {},
    markerIcon(i), element("span", { className: "car-name", text: name }), element("span", { className: "car-status" }))));
}

function canvasLabel(replay) {
  const finishers = Object.values(replay.rows).filter((r) => r.outcome === "finished").length;
  return `Race animation of ${replay.carCount} cars on seed ${replay.data.seed}'s track, ` +
    `${replay.seconds(replay.totalSteps).toFixed(1)} s long; ${finishers} finished. The legend and the table give each car's result.`;
}

function showClassification(replay, race) {
  const rows = race?.classification?.length ? race.classification : replay.data.classification || [];
  $("classification").tBodies[0].replaceChildren(...rows.map((row) => {
    const index = Number(String(row.car).replace("car_", ""));
    return element("tr", {},
      element("td", { className: "num", text: row.position }),
      element("td", {}, element("span", { className: "row" }, markerIcon(index), row.name)),
      element("td", { text: row.owner || "–" }),
      element("td", { text: row.outcome === "finished" ? "finished" : finalText(row) }),
      element("td", { className: "num", text: number(row.time, 2) }),
      element("td", { className: "num", text: number(row.distance, 3) }));
  }));
  const facts = [`seed ${replay.data.seed}`, `${replay.carCount} cars`, observationText(replay.data.observation)];
  const options = Object.entries(replay.data.env_options || {}).filter(([, v]) => v === false).map(([k]) => `no ${k.replaceAll("_", " ")}`);
  if (race) {
    facts.push(race.championship_id ? `championship ${race.championship_id}, round ${race.round}, heat ${race.heat}` : "friendly race");
    if (race.finished_at) facts.push(`run ${dateTime(race.finished_at)}`);
  }
  $("race-facts").textContent = [...facts, ...options].join(" · ");
}

/** A race's observation is lidar as soon as one car's agent reads lidar; compact agents then get
 * their 5-number view of it (league.evaluation.race), so the race's mode is not every car's. */
function observationText(mode) {
  return mode === "lidar" ? "lidar observations (compact agents get their 5-number view)" : `${mode} observations`;
}

// --------------------------------------------------------------------------- controls

/** The race's address at `step` ("Link to this moment" shows it for the step on screen). */
function linkToStep(step) {
  const url = new URL(location.href);
  url.searchParams.set("step", String(step));
  return url.href;
}

/** Paused: the address bar too says where, for a reload or a bookmark. */
function rememberStep() {
  if (raceId && viewer) history.replaceState(null, "", linkToStep(viewer.player.step));
}

onClick($("play-button"), () => viewer?.player.toggle());
$("speed").addEventListener("change", (event) => {
  if (viewer) viewer.player.speed = Number(event.target.value);
});
$("scrubber").addEventListener("input", (event) => {
  if (!viewer) return;
  viewer.player.seek(Number(event.target.value));
  if (!viewer.player.playing) rememberStep();
});
onClick($("copy-link"), async () => {
  $("share-link").select();
  try {
    await navigator.clipboard.writeText($("share-link").value);
    $("copy-status").textContent = "Copied.";
  } catch {
    $("copy-status").textContent = "Press Ctrl+C to copy the selected link.";
  }
});

document.addEventListener("keydown", (event) => {
  if (!viewer || event.altKey || event.ctrlKey || event.metaKey) return;
  const target = event.target;
  if (target.closest(".table-wrap")) return; // a table that scrolls sideways: the arrows scroll it
  const typing = target.matches("input[type=text], input[type=password], textarea, select");
  const onControl = target.matches("button, a, summary, input[type=range], input[type=file]");
  const { player, replay } = viewer;
  if (event.key === " " && !typing && !onControl) {
    event.preventDefault();
    player.toggle();
    return;
  }
  if (typing || target.matches("input[type=range]")) return; // the scrubber moves itself
  const second = Math.round(1 / replay.tstep);
  const moves = { ArrowLeft: -(event.shiftKey ? second : 1), ArrowRight: event.shiftKey ? second : 1 };
  if (event.key in moves) {
    event.preventDefault();
    player.pause();
    player.seek(player.step + moves[event.key]);
    rememberStep();
  } else if (event.key === "Home" || event.key === "End") {
    event.preventDefault();
    player.pause();
    player.seek(event.key === "Home" ? 0 : replay.totalSteps);
    rememberStep();
  }
});

// --------------------------------------------------------------------------- start

optionalUser().then(showAccount).catch(() => showAccount(null));
if (raceId) loadRace().catch((error) => say($("race-message"), `Race ${raceId} cannot be shown: ${error.message}`, "error"));
else openReplayFile();
