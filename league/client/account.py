"""`league login`: check a token with a league server and save both for the next commands."""
from __future__ import annotations

import argparse
import os

from league.client.api import Api, ClientError, Connection, store_login
from league.exit_codes import EXIT_ERROR, EXIT_OK


def run_login(args: argparse.Namespace) -> int:
    server = args.server or os.environ.get("LEAGUE_SERVER")
    if not server:
        raise ClientError("say which server: league login --server URL", EXIT_ERROR)
    token = args.token or os.environ.get("LEAGUE_TOKEN")
    if not token:
        import getpass

        token = getpass.getpass("API token (from your instructor): ").strip()
    with Api(Connection(server.rstrip("/"), token)) as api:
        me = api.get("/api/users/me")
    path = store_login(server.rstrip("/"), token)
    print(f"logged in to {server} as {me['name']} ({me['role']}); saved in {path}")
    return EXIT_OK


def add_commands(command) -> None:
    command("login", "check a token with a league server and save both for the next commands", run_login)
