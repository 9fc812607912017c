"""The league server's HTTP API as the client speaks it (httpx), and the credentials it uses.

The server and token come from --server/--token, else LEAGUE_SERVER/LEAGUE_TOKEN, else what
`league login` stored in the user's config directory (platformdirs; the file is readable by its
owner only). Every failure is a ClientError: one line for the user and its exit status.
"""
from __future__ import annotations

import argparse
import json
import os
from dataclasses import dataclass
from pathlib import Path

from league.exit_codes import EXIT_AUTH, EXIT_ERROR, EXIT_REFUSED, EXIT_UNREACHABLE


def poll_delays(first: float = 0.1, growth: float = 1.5, most: float = 1.0):
    """The pauses between a waiting command's looks at the server: short at first (an upload is
    often evaluated within a second), growing to one a second (a student waiting through a
    deadline's queue asks no more often than before)."""
    delay = first
    while True:
        yield delay
        delay = min(most, delay * growth)


class ClientError(Exception):
    """One line for the user and the exit status it means."""

    def __init__(self, message: str, exit_code: int):
        super().__init__(message)
        self.exit_code = exit_code


def config_path() -> Path:
    from platformdirs import user_config_dir

    return Path(user_config_dir("microracer-league")) / "client.json"


@dataclass(frozen=True)
class Connection:
    server: str
    token: str | None


def connection(args: argparse.Namespace, need_token: bool = True) -> Connection:
    stored = {}
    path = config_path()
    if path.is_file():
        stored = json.loads(path.read_text())
    server = args.server or os.environ.get("LEAGUE_SERVER") or stored.get("server")
    token = args.token or os.environ.get("LEAGUE_TOKEN") or stored.get("token")
    if not server:
        raise ClientError("no server: run `league login --server URL` or give --server URL (or LEAGUE_SERVER)",
                          EXIT_ERROR)
    if need_token and not token:
        raise ClientError("no token: run `league login` or give --token TOKEN (or LEAGUE_TOKEN)", EXIT_AUTH)
    return Connection(server.rstrip("/"), token)


def store_login(server: str, token: str) -> Path:
    """Write the server and token for the next commands, readable by this user only."""
    path = config_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_suffix(".tmp")
    temporary.unlink(missing_ok=True)
    with os.fdopen(os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600), "w") as handle:
        json.dump({"server": server, "token": token}, handle)
    os.replace(temporary, path)
    return path


class Api:
    """The server's API; every failure becomes a ClientError with the server's own words."""

    def __init__(self, conn: Connection, timeout: float = 60):
        import httpx

        self.conn = conn
        headers = {"Authorization": f"Bearer {conn.token}"} if conn.token else {}
        self.http = httpx.Client(base_url=conn.server, headers=headers, timeout=timeout)

    def __enter__(self) -> Api:
        return self

    def __exit__(self, *exc_info) -> None:
        self.http.close()

    def call(self, method: str, path: str, **kwargs):
        import httpx

        try:
            response = self.http.request(method, path, **kwargs)
        except httpx.HTTPError as error:
            raise ClientError(f"cannot reach the league server at {self.conn.server}: {error}",
                              EXIT_UNREACHABLE) from error
        if response.is_success:
            return response.json() if "json" in response.headers.get("content-type", "") else response.text
        detail = _detail(response)
        if response.status_code == 401:  # the server says why (replaced, revoked) and whom to ask
            raise ClientError(f"the server refused the token: {detail}; once you have a new one: "
                              f"league login --server {self.conn.server}", EXIT_AUTH)
        if response.status_code == 403:
            raise ClientError(f"the server refused: {detail}", EXIT_AUTH)
        if response.status_code >= 500:
            raise ClientError(f"the server failed ({response.status_code}): {detail}", EXIT_UNREACHABLE)
        raise ClientError(f"the server refused: {detail}", EXIT_REFUSED)

    def get(self, path: str, **params):
        return self.call("GET", path, params=params or None)


def _detail(response) -> str:
    try:
        detail = response.json().get("detail")
    except (ValueError, AttributeError):
        detail = None
    return detail if isinstance(detail, str) and detail else f"{response.status_code} {response.reason_phrase}"
