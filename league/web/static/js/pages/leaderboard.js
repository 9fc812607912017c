// The leaderboard page (/): championship standings, the course leaderboard, rounds and races,
// refreshed every 15 s. The token, when there is one, is sent: the course's board visibility decides
// who sees what (a visitor of a public board sees display names); a board closed to the visitor
// shows a prompt to log in, or the server's word on who may see it, instead of empty tables.

import { api, download } from "../api.js";
import { $, badge, element, onClick, replaceKeepingFocus, say } from "../dom.js";
import { dateTime, number, ordinal, percent } from "../format.js";
import { Pager } from "../pager.js";
import { Poller } from "../poller.js";
import { optionalUser, showAccount } from "../session.js";
import { SortableTable } from "../sortable-table.js";

const REFRESH_MS = 15000;
const BOARD_CALL = { loginOn401: false }; // a 401 here means "log in to see this board", said on the page
const PAGE_SIZE = 50;

let me = null;
const isOwn = (row) => Boolean(me && me.name && row.owner === me.name);

const standings = new SortableTable($("standings"), [
  { key: "rank", label: "Rank", numeric: true, better: "lower" },
  { key: "name", label: "Agent", render: (row) => raceableName(row) },
  { key: "owner", label: "Student" },
  { key: "points", label: "Points", numeric: true, better: "higher", render: pointsCell },
  { key: "wins", label: "Wins", numeric: true, better: "higher" },
  { key: "finishes", label: "Best finishes", numeric: true, better: "lower", value: bestFinish, render: finishesText },
  { key: "rating", label: "Rating", numeric: true, better: "higher", render: ratingCell },
], { rowKey: (row) => row.submission_id, isOwn, emptyText: "No standings yet: no round has been run." });

const STALE_TITLE = "Evaluated with other settings than the current ones: not ranked until it is evaluated again (queued).";

const leaderboard = new SortableTable($("leaderboard"), [
  { key: "rank", label: "Rank", numeric: true, better: "lower",
    render: (row) => (row.stale ? element("span", { attrs: { title: STALE_TITLE } }, badge("stale")) : String(row.rank)) },
  { key: "owner", label: "Student" },
  { key: "name", label: "Agent", render: (row) => raceableName(row) },
  { key: "completed", label: "Laps completed", numeric: true, better: "higher", value: completionRate,
    render: (row) => `${row.completed ?? "–"}/${row.episodes ?? "–"} (${percent(row.completed, row.episodes)})` },
  { key: "mean_return", label: "Mean return", numeric: true, better: "higher", render: (row) => number(row.mean_return, 2) },
  { key: "mean_speed", label: "Mean speed", numeric: true, better: "higher", render: (row) => number(row.mean_speed, 3) },
  { key: "mean_steps", label: "Mean steps", numeric: true, render: (row) => number(row.mean_steps, 0) },
  { key: "rating", label: "Rating", numeric: true, better: "higher", render: (row) => number(row.rating, 2) },
], { rowKey: (row) => row.submission_id, isOwn, apart: (row) => row.stale, emptyText: "No evaluated submissions yet." });

const standingsPager = new Pager($("standings-pager"), { size: PAGE_SIZE, label: "standings", onChange: refreshStandings });
const leaderboardPager = new Pager($("leaderboard-pager"), { size: PAGE_SIZE, label: "the leaderboard", onChange: refreshLeaderboard });

function raceableName(row) {
  return element("span", { text: row.name, attrs: { title: `submission ${row.submission_id}` } });
}

function completionRate(row) {
  return row.episodes ? row.completed / row.episodes : null;
}

function bestFinish(row) {
  return row.finishes.length ? Math.min(...row.finishes) : null;
}

function finishesText(row) {
  const positions = [...row.finishes].sort((a, b) => a - b).slice(0, 5);
  return positions.length ? positions.map(ordinal).join(", ") : "–";
}

/** The points, and for a row level on points with the row ranked above it, what put that one ahead. */
function pointsCell(row) {
  if (!row.tieBreak) return String(row.points);
  return element("span", {}, String(row.points), element("span", { className: "tie-break", text: row.tieBreak }));
}

/** The standings' tie-breaks (league/championship.py): wins, then 2nd places, 3rd places, ... */
function tieBreak(row, above) {
  if (!above || above.points !== row.points) return null;
  const count = (r, position) => r.finishes.filter((p) => p === position).length;
  const depth = Math.max(0, ...row.finishes, ...above.finishes);
  for (let position = 1; position <= depth; position++) {
    if (count(row, position) !== count(above, position)) {
      return `level on points with rank ${above.rank}: fewer ${position === 1 ? "wins" : `${ordinal(position)} places`}`;
    }
  }
  return `level with rank ${above.rank} on points and finishes`;
}

function ratingCell(row) {
  const text = number(row.rating, 2);
  if (row.mu === undefined || row.sigma === undefined) return text;
  return element("span", { text, attrs: { title: `μ ${number(row.mu, 2)}, σ ${number(row.sigma, 2)}` } });
}

// --------------------------------------------------------------------------- championships

let championshipId = new URLSearchParams(location.search).get("championship");

async function refreshChampionships() {
  const list = await api("/api/championships", BOARD_CALL);
  const picker = $("championship");
  const items = Array.isArray(list) ? list : list.items || [];
  standings.emptyText = items.length ? "No standings yet: no round has been run." : "No championship yet.";
  $("standings-csv").hidden = me?.role !== "instructor" || !items.length;
  if (!items.length) {
    standings.update([]);
    $("rounds").replaceChildren(element("li", { className: "muted", text: "No championship yet." }));
    return;
  }
  if (!items.some((c) => String(c.id) === String(championshipId))) {
    championshipId = String(Math.max(...items.map((c) => c.id)));
  }
  picker.replaceChildren(...items.map((c) => element("option", { text: c.name, attrs: { value: c.id } })));
  picker.value = championshipId;
  $("championship-picker").hidden = items.length < 2;
  $("standings-title").textContent = `Standings: ${items.find((c) => String(c.id) === championshipId).name}`;
  await Promise.all([refreshStandings(), refreshRounds()]);
}

async function refreshStandings() {
  if (!championshipId) return;
  const page = await api(`/api/championships/${championshipId}/standings?${standingsPager.query()}`, BOARD_CALL);
  const byRank = new Map(page.items.map((row) => [row.rank, row]));
  standings.update(page.items.map((row) => ({ ...row, tieBreak: tieBreak(row, byRank.get(row.rank - 1)) })));
  standingsPager.update(page.total);
}

async function refreshRounds() {
  const championship = await api(`/api/championships/${championshipId}`, BOARD_CALL);
  const rounds = championship.rounds || [];
  if (!rounds.length) {
    $("rounds").replaceChildren(element("li", { className: "muted", text: "No rounds yet." }));
    return;
  }
  replaceKeepingFocus($("rounds"), ...[...rounds].reverse().map((round) => {
    const item = element("li", {}, element("strong", { text: `Round ${round.number}` }), " ", badge(round.status),
      ` heats ${round.heats_done}/${round.heats_total}`);
    (round.race_ids || []).forEach((raceId, i) => {
      item.append(" · ", element("a", { text: `Heat ${i + 1} replay`, attrs: { href: `/races/${raceId}`, "data-focus-key": `race-${raceId}` } }));
    });
    return item;
  }));
}

$("championship").addEventListener("change", (event) => {
  championshipId = event.target.value;
  const url = new URL(location.href);
  url.searchParams.set("championship", championshipId);
  history.replaceState(null, "", url);
  standingsPager.page = 1;
  refreshChampionships().catch(showProblem("Standings"));
});

// --------------------------------------------------------------------------- leaderboard and races

// the board shown: the default one (/api/leaderboard), or a picked assignment's (logged-in members)
let assignments = [];
let assignmentId = new URLSearchParams(location.search).get("assignment");

async function loadAssignments() {
  assignments = me ? await api("/api/assignments").catch(() => []) : [];
  if (!assignments.length) return;
  if (!assignments.some((a) => String(a.id) === String(assignmentId))) assignmentId = String(assignments[0].id);
  $("assignment").replaceChildren(...assignments.map((a) => element("option", { text: a.name, attrs: { value: a.id } })));
  $("assignment").value = assignmentId;
  $("assignment-picker").hidden = false;
  showBoardKinds();
}

function showBoardKinds() {
  const published = Boolean(assignments.find((a) => String(a.id) === String(assignmentId))?.published_at);
  $("board-kind").querySelector("option[value=private]").disabled = !published;
  if (!published) $("board-kind").value = "public";
}

for (const id of ["assignment", "board-kind"]) {
  $(id).addEventListener("change", () => {
    assignmentId = $("assignment").value;
    showBoardKinds();
    const url = new URL(location.href);
    url.searchParams.set("assignment", assignmentId);
    history.replaceState(null, "", url);
    leaderboardPager.page = 1;
    refreshLeaderboard().catch(showProblem("Leaderboard"));
  });
}

async function refreshLeaderboard() {
  const path = assignmentId && assignments.length
    ? `/api/assignments/${assignmentId}/board?board=${$("board-kind").value}&` : "/api/leaderboard?";
  const page = await api(`${path}${leaderboardPager.query()}`, BOARD_CALL);
  leaderboard.update(page.items);
  leaderboardPager.update(page.total);
}

async function refreshRaces() {
  const page = await api("/api/races?page=1&size=10", BOARD_CALL);
  const items = page.items || [];
  if (!items.length) {
    $("races").replaceChildren(element("li", { className: "muted", text: "No races yet." }));
    return;
  }
  replaceKeepingFocus($("races"), ...items.map((race) => element("li", {},
    element("a", { text: `Race ${race.id}`, attrs: { href: `/races/${race.id}`, "data-focus-key": `race-${race.id}` } }), " ", badge(race.status), " ",
    element("span", { className: "muted", text: raceDescription(race) }))));
}

function raceDescription(race) {
  const what = race.championship_id ? `round ${race.round}, heat ${race.heat}` : "friendly race";
  const who = (race.entrants || []).map((e) => e.name).join(", ");
  return [what, who, dateTime(race.created_at)].filter(Boolean).join(" · ");
}

// --------------------------------------------------------------------------- refresh

const problems = new Map();
const closed = new Map(); // board ("leaderboard", "races") -> the 401/403 that closed it to this visitor

function showProblem(part, board) {
  return (error) => {
    if (board && (error.status === 401 || error.status === 403)) closed.set(board, error);
    else problems.set(part, `${part}: ${error.message}`);
  };
}

/** Hide the boards closed to this visitor; say why, with a log-in link when logging in would help. */
function showClosedBoards() {
  document.querySelectorAll("[data-board]").forEach((panel) => { panel.hidden = closed.has(panel.dataset.board); });
  const reason = closed.get("leaderboard") || closed.get("races");
  const box = $("board-closed");
  box.hidden = !reason;
  if (!reason) return;
  const login = element("a", { text: "Log in with your token", attrs: { href: `/login?next=${encodeURIComponent("/")}` } });
  box.replaceChildren(element("strong", { text: reason.status === 401 ? "Log in to see the boards." : "These boards are not shown to you." }),
    ` The server says: ${reason.message}.`, ...(reason.status === 401 ? [" ", login, "."] : []));
}

async function refreshAll() {
  problems.clear();
  closed.clear();
  await Promise.all([
    refreshChampionships().catch(showProblem("Standings", "leaderboard")),
    refreshLeaderboard().catch(showProblem("Leaderboard", "leaderboard")),
    refreshRaces().catch(showProblem("Races", "races")),
  ]);
  showClosedBoards();
  say($("notice"), [...problems.values()].join(" "), "info");
  $("updated").textContent = `Updated ${new Date().toLocaleTimeString()}`;
  return $("auto-refresh").checked;
}

// --------------------------------------------------------------------------- grades (instructors)

onClick($("standings-csv"), () => download(`/api/championships/${championshipId}/standings.csv`,
  `standings-${championshipId}.csv`).catch(showProblemNow("Standings CSV")));
onClick($("leaderboard-csv"), () => (assignmentId && assignments.length
  ? download(`/api/assignments/${assignmentId}/board.csv?board=${$("board-kind").value}`, `assignment-${assignmentId}.csv`)
  : download("/api/leaderboard.csv", "leaderboard.csv")).catch(showProblemNow("Grades CSV")));

function showProblemNow(part) {
  return (error) => say($("notice"), `${part}: ${error.message}`, "error");
}

const refresher = new Poller(refreshAll, REFRESH_MS);
$("auto-refresh").addEventListener("change", (event) => (event.target.checked ? refresher.poll() : refresher.stop()));
onClick($("refresh-now"), () => refresher.poll());

async function start() {
  me = await optionalUser().catch(() => null);
  showAccount(me);
  if (me && me.expired) {
    say($("account-notice"), `Your token is no longer valid (${me.reason}); log in again to see your rows highlighted.`, "info");
    me = null;
  }
  document.querySelectorAll("[data-instructor]").forEach((button) => { button.hidden = me?.role !== "instructor"; });
  await loadAssignments();
  refresher.poll();
}

start();
