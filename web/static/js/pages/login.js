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

/** Only paths of this site: "/x" but not "//host/x". */
function nextPage(user) {
  const next = new URLSearchParams(location.search).get("next");
  if (next && next.startsWith("/") && !next.startsWith("//") && !next.startsWith("/login")) return next;
  return user.role === "instructor" ? "/instructor" : "/submissions";
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
