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

/** Only pages of this site, judged as the browser resolves the address ("/\\host" is another site). */
function nextPage(user) {
  const next = new URLSearchParams(location.search).get("next");
  if (next) {
    const target = new URL(next, location.origin);
    if (target.origin === location.origin && !target.pathname.startsWith("/login")) {
      return target.pathname + target.search + target.hash;
    }
  }
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
