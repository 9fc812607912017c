"""The client's commands in the `league` parser: the server options each takes, the exit codes each
lists, and the groups of commands in the order `league --help` shows them."""
from __future__ import annotations

import argparse

from league.client import (
    account, assignments, championships, check, grades, instructor, leaderboard, races, submissions,
)
from league.exit_codes import CLIENT_EXIT_CODES

GROUPS = (account, check, submissions, leaderboard, assignments, grades, championships, instructor, races)


def add_commands(subparsers) -> None:
    """Add every client command to the `league` command's subparsers (league/cli.py)."""
    command = command_maker(subparsers)
    for group in GROUPS:
        group.add_commands(command)


def command_maker(subparsers):
    """`command(name, help, run, description)`: a subcommand that takes --server and --token, lists the
    exit codes and runs `run(args)`."""
    server = argparse.ArgumentParser(add_help=False)
    group = server.add_argument_group("server (else LEAGUE_SERVER / LEAGUE_TOKEN, else what `league login` saved)")
    group.add_argument("--server", metavar="URL", help="the league server, e.g. https://league.example.org")
    group.add_argument("--token", help="your API token")

    def command(name: str, help_: str, run, description: str | None = None) -> argparse.ArgumentParser:
        parser = subparsers.add_parser(name, parents=[server], help=help_, description=description or help_,
                                       epilog=CLIENT_EXIT_CODES, formatter_class=argparse.RawDescriptionHelpFormatter)
        parser.set_defaults(run=run)
        return parser

    return command
