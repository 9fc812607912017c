// Students: create one or a roster (their tokens are shown once, kept until dismissed; the roster's
// lines not created listed), revoke (after a confirmation), issue a new token.

import { api } from "../api.js";
import { $, badge, element, focusOn, onClick, onSubmit, replaceKeepingFocus, say } from "../dom.js";
import { count, dateTime } from "../format.js";


let tokens = []; // [{id, name, email, student_id, token}], newest first: shown until the instructor dismisses them

export function setUpStudents(me) {
  onClick($("tokens-dismiss"), () => {
    showTokens([], { dismiss: true });
    focusOn($("student-name"));
  });
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
      const report = await api("/api/users/roster", { method: "POST", form });
      $("roster-form").reset();
      if (report.created.length) showTokens(report.created);
      showRosterLines(report);
      await refreshUsers(me);
      say($("students-message"), rosterSummary(report, file.name), report.errors.length ? "error" : "success");
    } catch (error) {
      $("roster-report").hidden = true;
      say($("students-message"), `The roster was not read: ${error.message}`, "error");
    }
  });
  return refreshUsers(me);
}

// Lines are independent: the server creates the good ones and lists the others with their numbers.
function rosterSummary({ format, created, skipped, errors }, filename) {
  const columns = Object.values(format.columns);
  const read = columns.length ? `${format.delimiter}-separated, columns ${columns.join(", ")}` : "one name a line";
  const parts = [`Created ${count(created.length, "student")} from ${filename} (${read}).`];
  if (skipped.length) parts.push(`Skipped ${count(skipped.length, "line")} naming students already enrolled.`);
  if (errors.length) parts.push(`${count(errors.length, "line")} with errors not created: fix them and upload the roster again.`);
  return parts.join(" ");
}

function showRosterLines({ skipped, errors }) {
  const lines = [...errors.map((line) => ({ ...line, error: true })), ...skipped].sort((a, b) => a.line - b.line);
  $("roster-report").hidden = !lines.length;
  $("roster-lines").tBodies[0].replaceChildren(...lines.map((line) => element("tr", {},
    element("td", { text: String(line.line) }), element("td", { text: line.name ?? "–" }),
    element("td", {}, line.error ? badge("rejected", "error") : badge("pending", "skipped")),
    element("td", { text: line.reason }))));
}

/** Add new tokens above those shown (a user's new token replaces their earlier one), or dismiss them all. */
function showTokens(users, { dismiss = false, revoked = null } = {}) {
  const replaced = new Set([...users.map((user) => user.id), revoked]);
  tokens = dismiss ? [] : [...users, ...tokens.filter((shown) => !replaced.has(shown.id))];
  $("tokens").hidden = !tokens.length;
  $("token-table").tBodies[0].replaceChildren(...tokens.map((user) => element("tr", {},
    element("td", { text: user.name }), element("td", {}, element("span", { className: "token", text: user.token })))));
  const csv = ["name,email,student_id,token", ...tokens.map((user) =>
    [user.name, user.email ?? "", user.student_id ?? "", user.token].map(csvCell).join(","))].join("\n");
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
  replaceKeepingFocus($("users").tBodies[0], ...users.map((user) => {
    const actions = element("span", { className: "row" });
    if (user.id !== me.id && user.role === "student") {
      const tokenKey = `token-${user.id}`;
      if (user.active) actions.append(actionButton(`Revoke`, `Revoke ${user.name}'s account`, "danger", async () => {
        await api(`/api/users/${user.id}/revoke`, { method: "POST" });
        showTokens([], { revoked: user.id });
        say($("students-message"), `${user.name}'s token no longer works.`, "success");
      }, me, { key: `revoke-${user.id}`, next: tokenKey, ask: () => askToRevoke(user) }));
      actions.append(actionButton("Delete", `Delete ${user.name} and their data`, "danger", async () => {
        await api(`/api/users/${user.id}`, { method: "DELETE" });
        showTokens([], { revoked: user.id });
        say($("students-message"), `${user.name} and their data are deleted.`, "success");
      }, me, { key: `delete-${user.id}`, ask: () => askToDelete(user) }));
      const newToken = user.active ? "New token" : "Restore with a new token";
      actions.append(actionButton(newToken, `${newToken} for ${user.name}`, "secondary", async () => {
        const created = await api(`/api/users/${user.id}/token`, { method: "POST" });
        showTokens([created]);
        say($("students-message"), `New token for ${user.name} below (the old one no longer works).`, "success");
      }, me, { key: tokenKey }));
    }
    const identifiers = [user.email, user.student_id].filter(Boolean).join(" · ");  // under the name: the table fits its card
    return element("tr", {}, element("td", {}, user.name,
      identifiers ? element("span", { className: "subline muted", text: identifiers }) : null),
      element("td", { text: user.role }),
      element("td", { text: dateTime(user.created_at) }),
      element("td", {}, user.active ? badge("ready", "active") : badge("rejected", "revoked")), element("td", {}, actions));
  }));
}

/** A user's action; `ask` may ask first. Once done, the focus goes to the button keyed `next` in the redrawn row. */
function actionButton(text, label, style, action, me, { key, next = key, ask = async () => true }) {
  const button = element("button", { className: `small ${style}`, text, attrs: { type: "button", "aria-label": label, "data-focus-key": key } });
  button.addEventListener("click", async () => {
    if (!(await ask())) {
      button.focus();
      return;
    }
    button.disabled = true; // which takes its focus: given back below
    try {
      await action();
      await refreshUsers(me);
      focusOn($("users").querySelector(`[data-focus-key="${next}"]`));
    } catch (error) {
      say($("students-message"), error.message, "error");
      button.disabled = false;
      button.focus();
    }
  });
  return button;
}

/** Deleting cannot be undone: a dialog says what goes and what stays, its Cancel button focused. */
function askToDelete(user) {
  const dialog = $("delete-dialog");
  $("delete-title").textContent = `Delete ${user.name} and their data?`;
  $("delete-summary").textContent = `${user.name}'s account, token, submissions, model files and evaluations are ` +
    "erased for good (backups taken before still hold them). Races and championship standings other students " +
    "took part in keep their results, with this student shown as “deleted student”. This cannot be undone.";
  dialog.returnValue = "";
  dialog.showModal();
  return new Promise((resolve) => {
    dialog.addEventListener("close", () => resolve(dialog.returnValue === "delete"), { once: true });
  });
}

/** Revoking logs the student out at once: a dialog asks first, its Cancel button focused. */
function askToRevoke(user) {
  const dialog = $("revoke-dialog");
  $("revoke-title").textContent = `Revoke ${user.name}'s account?`;
  $("revoke-summary").textContent = `${user.name}'s token stops working at once: they are logged out and can no longer ` +
    "upload or race. Their submissions and results stay. “Restore with a new token” gives them a new one.";
  dialog.returnValue = "";
  dialog.showModal();
  return new Promise((resolve) => {
    dialog.addEventListener("close", () => resolve(dialog.returnValue === "revoke"), { once: true });
  });
}
