// The console's audit log: who did what (GET /api/audit), newest first; the whole log as CSV.

import { api, download } from "../api.js";
import { $, element, onClick, replaceKeepingFocus, say } from "../dom.js";
import { dateTime } from "../format.js";

const SHOWN = 50; // the newest events; the CSV holds them all

/** "submissions=2, races_kept=1": an event's details as one line. */
function detailsText(details) {
  return Object.entries(details).map(([key, value]) =>
    `${key}=${typeof value === "object" && value !== null ? JSON.stringify(value) : value}`).join(", ");
}

async function refreshAudit() {
  const page = await api(`/api/audit?size=${SHOWN}`);
  replaceKeepingFocus($("audit").tBodies[0], ...page.items.map((event) => element("tr", {},
    element("td", { text: dateTime(event.at) }),
    element("td", { text: event.actor_name }),
    element("td", { text: event.action }),
    element("td", { text: event.target_id === null ? event.target_kind : `${event.target_kind} #${event.target_id}` }),
    element("td", { text: detailsText(event.details) }))));
  if (page.total > SHOWN) say($("audit-message"), `The newest ${SHOWN} of ${page.total} events; the CSV holds them all.`, "info");
}

export async function setUpAudit() {
  onClick($("refresh-audit"), () => refreshAudit().catch((error) => say($("audit-message"), error.message, "error")));
  onClick($("audit-csv"), () => download("/api/audit.csv", "audit.csv")
    .catch((error) => say($("audit-message"), error.message, "error")));
  await refreshAudit();
}
