// Talking to the league server: JSON over fetch, the API token kept in localStorage, and every
// error turned into the server's own human-readable text ({"detail": ...}).

const TOKEN_KEY = "league.token";
const LOGIN_MESSAGE_KEY = "league.loginMessage";

export function storedToken() {
  return localStorage.getItem(TOKEN_KEY);
}

export function storeToken(token) {
  localStorage.setItem(TOKEN_KEY, token);
}

export function forgetToken() {
  localStorage.removeItem(TOKEN_KEY);
}

export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

/** Go to the login page, which will show `message` and come back here afterwards. */
export function sendToLogin(message) {
  forgetToken();
  if (message) sessionStorage.setItem(LOGIN_MESSAGE_KEY, message);
  const back = location.pathname + location.search;
  location.assign(`/login?next=${encodeURIComponent(back)}`);
}

/** The message left for the login page by sendToLogin (read once). */
export function takeLoginMessage() {
  const message = sessionStorage.getItem(LOGIN_MESSAGE_KEY);
  sessionStorage.removeItem(LOGIN_MESSAGE_KEY);
  return message;
}

/**
 * Call the API. Options: method, json (a body to send as JSON), form (a FormData), auth (send the
 * token, default true), loginOn401 (default true: a rejected token sends the user to log in).
 * Resolves to the parsed JSON (null for an empty body); rejects with an ApiError.
 */
export async function api(path, { method = "GET", json, form, auth = true, loginOn401 = true, signal } = {}) {
  const headers = { Accept: "application/json" };
  const token = storedToken();
  if (auth && token) headers.Authorization = `Bearer ${token}`;
  let body;
  if (json !== undefined) {
    headers["Content-Type"] = "application/json";
    body = JSON.stringify(json);
  } else if (form) {
    body = form;
  }
  let response;
  try {
    response = await fetch(path, { method, headers, body, signal });
  } catch (error) {
    if (error.name === "AbortError") throw error;
    throw new ApiError(0, "The server cannot be reached; check your connection and try again.");
  }
  const data = await readBody(response);
  if (response.ok) return data;
  const message = errorText(response, data);
  if (response.status === 401 && auth && loginOn401) {
    sendToLogin(`You were logged out: ${message}. Log in again with your token.`);
  }
  throw new ApiError(response.status, message);
}

/** Fetch a file with the token (a link could not send it) and save it as `filename`. */
export async function download(path, filename) {
  const response = await fetch(path, { headers: { Authorization: `Bearer ${storedToken()}` } });
  if (!response.ok) throw new ApiError(response.status, errorText(response, await readBody(response)));
  const link = document.createElement("a");
  link.href = URL.createObjectURL(await response.blob());
  link.download = filename;
  link.click();
  setTimeout(() => URL.revokeObjectURL(link.href), 60000);
}

async function readBody(response) {
  const text = await response.text();
  if (!text) return null;
  try {
    return JSON.parse(text);
  } catch {
    return text;
  }
}

/** FastAPI errors: {"detail": "text"} or, for invalid input, {"detail": [{loc, msg}, ...]}. */
function errorText(response, data) {
  const detail = data && typeof data === "object" ? data.detail : data;
  if (typeof detail === "string" && detail) return detail;
  if (Array.isArray(detail)) {
    return detail.map((item) => {
      const where = (item.loc || []).filter((part) => part !== "body").join(".");
      return where ? `${where}: ${item.msg}` : item.msg;
    }).join("; ");
  }
  return `${response.status} ${response.statusText || "error"}`;
}
