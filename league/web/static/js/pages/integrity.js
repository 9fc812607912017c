// The integrity report (/integrity, instructors): groups of copied submissions, the CSV, and
// probing the submissions whose behaviour is not known yet.

import { api, download } from "../api.js";
import { $, element, onClick, replaceKeepingFocus, say } from "../dom.js";
import { count, dateTime } from "../format.js";
import { requireInstructor } from "../session.js";

const KINDS = { identical_file: "Identical file", same_behaviour: "Same behaviour", baseline_copy: "Baseline copy" };

function submissionItem(s) {
  const what = `#${s.id} ${s.name} (${s.owner}, ${s.kind}, ${dateTime(s.created_at)})`;
  return element("li", {}, element("span", { text: what }), element("br"),
    element("code", { className: "small", text: s.sha256.slice(0, 16), attrs: { title: s.sha256 } }));
}

function groupRow(group, number) {
  const kind = KINDS[group.kind] + (group.baseline ? `: ${group.baseline}` : "");
  return element("tr", {},
    element("td", { className: "num", text: number }), element("td", { text: kind }),
    element("td", { text: group.students.join(", ") }),
    element("td", {}, element("ul", { className: "plain" }, ...group.submissions.map(submissionItem))),
    element("td", { className: "num", text: distanceText(group.distance) }));
}

/** "–" when unknown, 0, else two significant digits (1.2e-7: rounding; 0.8: another agent). */
function distanceText(distance) {
  if (distance === null) return "–";
  return distance === 0 ? "0" : distance.toExponential(1);
}

async function refresh() {
  const report = await api("/api/integrity");
  $("integrity-summary").textContent = `${count(report.submissions, "ready submission")}, ` +
    `${report.compared} compared on every probe set of ${report.probes} observations (same behaviour: a ` +
    `distance within ${report.tolerance}); ${count(report.groups.length, "group")}.`;
  const rows = report.groups.map((group, i) => groupRow(group, i + 1));
  if (!rows.length) rows.push(element("tr", {}, element("td", { text: "No copies found.", attrs: { colspan: 5 } })));
  replaceKeepingFocus($("integrity-groups").tBodies[0], ...rows);
  $("uncompared").hidden = !report.not_compared.length;
  replaceKeepingFocus($("uncompared-table").tBodies[0], ...report.not_compared.map((s) => element("tr", {},
    element("td", { className: "num", text: s.id }), element("td", { text: s.owner }),
    element("td", { text: s.name }), element("td", { text: s.reason }))));
}

async function probe() {
  const { queued } = await api("/api/integrity/probe", { method: "POST" });
  say($("integrity-message"), queued.length ? `${count(queued.length, "submission")} queued to be probed, after ` +
    "the students' own uploads; refresh in a while." : "Nothing to queue: they are being probed, or failed on the " +
    "probe set.", "success");
}

async function start() {
  if (!(await requireInstructor())) return;
  const failed = (error) => say($("integrity-message"), error.message, "error");
  onClick($("integrity-refresh"), () => refresh().catch(failed));
  onClick($("integrity-csv"), () => download("/api/integrity.csv", "integrity.csv").catch(failed));
  onClick($("integrity-probe"), () => probe().catch(failed));
  await refresh().catch(failed);
}

start();
