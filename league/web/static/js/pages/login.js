// The login page: check the token with the server, keep it in localStorage, go back where the
// user came from (or to their home page).

import { api, forgetToken, storeToken, takeLoginMessage } from "../api.js";
import { $, onSubmit, say } from "../dom.js";

const input = $("token");
const message = $("login-message");

const left = takeLoginMessage();
if (left) say(message, left, "error");
input.focus();

$("show-token").addEventListener("change", (event) => {
  input.type = event.target.checked ? "text" : "password";
});

/** The `next` address if it is a page of this site, else null. Judged on the text first, then as
 * the browser resolves it: one leading "/" (no scheme), no "//" nor "\" in the path ("//host" and
 * "/\host" are other sites, and "/.//host" resolves to "//host"), no control characters (the
 * browser drops tabs and newlines: "/\t/host" is "//host"). */
function samePage(next) {
  const path = next.split(/[?#]/, 1)[0];
  if (!next.startsWith("/") || path.includes("//") || next.includes("\\") || /[\u0000-\u001f\u007f]/.test(next)) {
    return null;
  }
  const target = new URL(next, location.origin);
  if (target.origin !== location.origin || target.pathname.startsWith("//") || target.pathname.startsWith("/login")) {
    return null;
  }
  return target.pathname + target.search + target.hash;
}

function nextPage(user) {
  const next = new URLSearchParams(location.search).get("next");
  return (next && samePage(next)) || (user.role === "instructor" ? "/instructor" : "/submissions");
}

onSubmit($("login-form"), async () => {
  const token = input.value.trim();
  if (!token) {
    say(message, "Enter your token.", "error");
    input.focus();
    return;
  }
  storeToken(token);
  try {
    const user = await api("/api/users/me", { loginOn401: false });
    location.assign(nextPage(user));
  } catch (error) {
    forgetToken();
    say(message, error.status === 401 ? `This token was not accepted: ${error.message}.` : error.message, "error");
    input.select();
  }
});
