// Students: create one or a CSV roster (their tokens are shown once), revoke, issue a new token.

import { api } from "../api.js";
import { $, badge, element, onSubmit, say } from "../dom.js";
import { count, dateTime } from "../format.js";


export function setUpStudents(me) {
  onSubmit($("student-form"), async () => {
    const name = $("student-name").value.trim();
    if (!name) {
      say($("students-message"), "Enter the student's name.", "error");
      return;
    }
    try {
      const created = await api("/api/users", { method: "POST", json: { name } });
      $("student-name").value = "";
      showTokens([created]);
      await refreshUsers(me);
      say($("students-message"), `Created ${created.name}. Give them the token below.`, "success");
    } catch (error) {
      say($("students-message"), `Not created: ${error.message}`, "error");
    }
  });

  onSubmit($("roster-form"), async () => {
    const file = $("roster-file").files[0];
    if (!file) {
      say($("students-message"), "Choose a CSV file first.", "error");
      return;
    }
    const form = new FormData();
    form.append("file", file, file.name);
    try {
      const { created, skipped } = await api("/api/users/roster", { method: "POST", form });
      $("roster-form").reset();
      if (created.length) showTokens(created);
      await refreshUsers(me);
      const already = skipped.length ? ` Skipped ${count(skipped.length, "name")} already taken: ${skipped.join(", ")}.` : "";
      say($("students-message"), `Created ${count(created.length, "student")} from ${file.name}.${already}`, "success");
    } catch (error) {
      say($("students-message"), `The roster was not created: ${error.message}`, "error");
    }
  });
  return refreshUsers(me);
}

function showTokens(users) {
  $("tokens").hidden = false;
  $("token-table").tBodies[0].replaceChildren(...users.map((user) => element("tr", {},
    element("td", { text: user.name }), element("td", {}, element("span", { className: "token", text: user.token })))));
  const csv = ["name,token", ...users.map((user) => `${csvCell(user.name)},${csvCell(user.token)}`)].join("\n");
  const link = $("tokens-download");
  if (link.href.startsWith("blob:")) URL.revokeObjectURL(link.href);
  link.href = URL.createObjectURL(new Blob([csv + "\n"], { type: "text/csv" }));
}

// A cell no spreadsheet runs as a formula, whatever it splits lines on: the rule of league/spreadsheet.py.
function csvCell(text) {
  let safe = "";
  let cellMayBegin = true;
  for (const char of text.replace(/[\p{Cc}\p{Zl}\p{Zp}]/gu, " ")) {
    if (cellMayBegin && "=+-@".includes(char)) safe += "'";
    safe += char;
    cellMayBegin = ",;|".includes(char) || (cellMayBegin && ` "'`.includes(char));
  }
  return `"${safe.replaceAll('"', '""')}"`;
}

async function refreshUsers(me) {
  const users = await api("/api/users");
  $("users").tBodies[0].replaceChildren(...users.map((user) => {
    const actions = element("span", { className: "row" });
    if (user.id !== me.id && user.role === "student") {
      if (user.active) actions.append(actionButton(`Revoke`, `Revoke ${user.name}'s account`, "danger", async () => {
        await api(`/api/users/${user.id}/revoke`, { method: "POST" });
        say($("students-message"), `${user.name}'s token no longer works.`, "success");
      }, me));
      actions.append(actionButton(user.active ? "New token" : "Restore with a new token", `New token for ${user.name}`, "secondary", async () => {
        const created = await api(`/api/users/${user.id}/token`, { method: "POST" });
        showTokens([created]);
        say($("students-message"), `New token for ${user.name} below (the old one no longer works).`, "success");
      }, me));
    }
    return element("tr", {}, element("td", { text: user.name }), element("td", { text: user.role }),
      element("td", { text: dateTime(user.created_at) }),
      element("td", {}, user.active ? badge("ready", "active") : badge("rejected", "revoked")), element("td", {}, actions));
  }));
}

function actionButton(text, label, style, action, me) {
  const button = element("button", { className: `small ${style}`, text, attrs: { type: "button", "aria-label": label } });
  button.addEventListener("click", async () => {
    button.disabled = true;
    try {
      await action();
      await refreshUsers(me);
    } catch (error) {
      say($("students-message"), error.message, "error");
      button.disabled = false;
    }
  });
  return button;
}
