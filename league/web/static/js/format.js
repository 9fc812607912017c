// Numbers, dates and the race texts, worded as the toolkit words them (league/render.py).

export function number(value, digits = 2) {
  return value === null || value === undefined || Number.isNaN(value) ? "–" : Number(value).toFixed(digits);
}

export function percent(part, whole) {
  return whole ? `${Math.round((100 * part) / whole)} %` : "–";
}

export function dateTime(iso) {
  if (!iso) return "–";
  const date = new Date(iso);
  return Number.isNaN(date.getTime()) ? iso : date.toLocaleString([], { dateStyle: "medium", timeStyle: "short" });
}

/** "1 job", "2 jobs". */
export function count(n, noun, plural = `${noun}s`) {
  return `${n} ${n === 1 ? noun : plural}`;
}

export function ordinal(n) {
  const suffix = n % 100 >= 10 && n % 100 <= 20 ? "th" : { 1: "st", 2: "nd", 3: "rd" }[n % 10] || "th";
  return `${n}${suffix}`;
}

// How a car's episode or race ended, in words: the toolkit's table (league.evaluation.OUTCOME_TEXT),
// which the server writes into every page.
const OUTCOME_TEXT = JSON.parse(document.body.dataset.outcomeText);

/** "off road" for off_road; an outcome the table does not know (a car still "running") as it is. */
export function outcomeText(outcome) {
  return OUTCOME_TEXT[outcome] || outcome;
}

/** The thesis' legend line: "accelerating 0.52 | right 0.31 | speed 0.27" (positive turn = right). */
export function actionText(acc, turn, speed) {
  const throttle = acc >= 0 ? `accelerating ${acc.toFixed(2)}` : `braking ${(-acc).toFixed(2)}`;
  const steering = turn === 0 ? "straight" : turn > 0 ? `right ${turn.toFixed(2)}` : `left ${(-turn).toFixed(2)}`;
  return `${throttle} | ${steering} | speed ${speed.toFixed(2)}`;
}

/** A car's line once it stopped: "1st 27.3 s", or why it stopped ("off road", "DNF: ..."). */
export function finalText(row) {
  if (row.outcome === "finished") return `${ordinal(row.position)}  ${row.time.toFixed(1)} s`;
  if (row.outcome === "dnf") return `DNF: ${row.reason || "agent failed"}`;
  return outcomeText(row.outcome);
}

/** A time in the viewer's own time zone, with the zone named: "1 Dec 2026, 23:59 CET". */
export function zonedTime(iso) {
  if (!iso) return "–";
  const date = new Date(iso);
  return Number.isNaN(date.getTime()) ? iso
    // (dateStyle and timeStyle refuse timeZoneName: a TypeError that left the tables unfilled)
    : date.toLocaleString([], { year: "numeric", month: "short", day: "numeric", hour: "2-digit", minute: "2-digit",
                                timeZoneName: "short" });
}

/**
 * What is left from `now` (the server's clock) to `until`: "3 d 4 h", "5 h 12 min", "under a minute",
 * "passed". Rounded down, so never more than is left; the last minute is "under a minute", not 0.
 */
export function timeLeft(until, now) {
  if (!until) return "no deadline";
  const left = new Date(until) - new Date(now);
  if (left <= 0) return "passed";
  const minutes = Math.floor(left / 60000);
  if (minutes < 1) return "under a minute";
  const days = Math.floor(minutes / 1440);
  const hours = Math.floor((minutes % 1440) / 60);
  return days ? `${days} d ${hours} h` : `${hours} h ${minutes % 60} min`;
}

/** An assignment's time left to upload (the API's answer): to the due time, then (state "late") to the late window's end. */
export function uploadTimeLeft(a) {
  if (a.state === "closed") return "closed";
  if (a.state === "late") return `due time passed; late uploads: ${timeLeft(a.my_closes_at, a.now)} left`;
  return timeLeft(a.my_due_at, a.now);
}
