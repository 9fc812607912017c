// Who is logged in, and the header that says so.

import { api, forgetToken, sendToLogin, storedToken } from "./api.js";
import { $, say } from "./dom.js";

/** The logged-in user ({id, name, role, ...}) or null; a stale token is dropped, not followed. */
export async function optionalUser() {
  if (!storedToken()) return null;
  try {
    return await api("/api/users/me", { loginOn401: false });
  } catch (error) {
    if (error.status === 401) {
      forgetToken();
      return { expired: true, reason: error.message };
    }
    throw error;
  }
}

/** The logged-in user; without a valid token, go to the login page (with the server's reason). */
export async function requireUser({ role } = {}) {
  if (!storedToken()) {
    sendToLogin("Log in with your token to see this page.");
    return new Promise(() => {}); // the page is leaving
  }
  const user = await api("/api/users/me");
  if (role && user.role !== role) {
    throw new Error(`This page is for ${role}s; you are logged in as ${user.name} (${user.role}).`);
  }
  return user;
}

/**
 * The start of an instructors' page: the logged-in instructor, the header filled. Anyone else gets
 * null, the reason in the page's #page-message and the page's panels hidden.
 */
export async function requireInstructor() {
  let me;
  try {
    me = await requireUser({ role: "instructor" });
  } catch (error) {
    say($("page-message"), error.message, "error");
    document.querySelectorAll("main section, main .grid-2").forEach((part) => (part.hidden = true));
    return null;
  }
  showAccount(me);
  return me;
}

/** Fill the header's account area: the user's name and a log-out button, or a log-in link. */
export function showAccount(user) {
  const area = document.querySelector("[data-account]");
  if (!area) return;
  area.replaceChildren();
  document.querySelectorAll("[data-role-link]").forEach((link) => {
    link.hidden = !user || user.expired || link.dataset.roleLink.split(" ").indexOf(user.role) < 0;
  });
  if (!user || user.expired) {
    const login = document.createElement("a");
    login.href = `/login?next=${encodeURIComponent(location.pathname + location.search)}`;
    login.textContent = "Log in";
    login.className = "button secondary small";
    area.append(login);
    return;
  }
  const name = document.createElement("span");
  name.textContent = `${user.name} (${user.role})`;
  name.dataset.testid = "account-name";
  const logout = document.createElement("button");
  logout.type = "button";
  logout.className = "small";
  logout.textContent = "Log out";
  logout.addEventListener("click", () => {
    forgetToken();
    location.assign("/login");
  });
  area.append(name, logout);
}
