"""What every group of `league` commands shares: running one (`run`: errors as one line, the exit
status, a closed pipe) and the options several groups take (--version, the env's --no-OPTION switches).

league/cli.py composes the `league` command from the groups (the toolkit's, the baselines', the
client's, the server's); `python -m league.server` runs the server's alone (league/server/cli.py).
Both run it here, so that no group imports the composition.
"""
from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence

from league.exit_codes import EXIT_CLOSED_PIPE, EXIT_ERROR, EXIT_INTERRUPTED

ENV_SWITCHES = {  # option -> what --no-OPTION does
    "obstacles": "no obstacles on the track",
    "chicanes": "no chicane on the track",
    "turn_limit": "no speed-dependent turn limit",
    "low_speed_termination": "do not end episodes below speed 0.05",
}


def add_env_switches(group) -> None:
    """`--no-obstacles`, `--no-chicanes`, ...: each switches an env option (on by default) off."""
    for switch, effect in ENV_SWITCHES.items():
        group.add_argument(f"--no-{switch.replace('_', '-')}", dest=switch, action="store_false", help=effect)


def env_options(args: argparse.Namespace) -> dict:
    return {switch: getattr(args, switch) for switch in ENV_SWITCHES}


def add_version(parser: argparse.ArgumentParser) -> None:
    """`--version`: the package's version (its one home is pyproject.toml, read from the installed metadata)."""
    from league import __version__

    parser.add_argument("--version", action="version", version=f"%(prog)s (microracer-league) {__version__}")


class UsageError(Exception):
    """A mistake in the command line that argparse cannot see."""


def run(parser: argparse.ArgumentParser, argv: Sequence[str] | None = None) -> int:
    """Parse `argv` and run its command; returns the exit status."""
    try:
        try:
            status = _run(parser, argv)
        except SystemExit as done:  # argparse: --help, or a mistake in the command line
            if not isinstance(done.code, (int, type(None))):
                raise  # a message for Python to print
            status = done.code or 0
        sys.stdout.flush()  # what is left goes out here, where a closed pipe can still be handled
        return status
    except BrokenPipeError as error:
        if not reader_gone(sys.stdout):  # another pipe (a sandbox's, say) broke: an error like any other
            return _report(error)
        # `league ... | head`: the reader has what it wanted. The interpreter's last flush goes nowhere.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_CLOSED_PIPE


def _run(parser: argparse.ArgumentParser, argv: Sequence[str] | None) -> int:
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except KeyboardInterrupt:
        print("league: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        raise
    except Exception as error:  # one line for the user, never a traceback (unless LEAGUE_DEBUG)
        return _report(error)


def _report(error: Exception) -> int:
    if os.environ.get("LEAGUE_DEBUG"):
        raise error
    print(f"league: error: {_describe(error)}", file=sys.stderr)
    return getattr(error, "exit_code", EXIT_ERROR)  # the client's errors carry theirs (league.client.api)


def reader_gone(stream) -> bool:
    """Whether the pipe `stream` writes to has lost its reader (`league ... | head` once head quit):
    poll reports an error on such a pipe; never on a terminal or a file."""
    import select

    try:
        poller = select.poll()  # not on Windows: there a broken pipe is reported as an error
        poller.register(stream.fileno(), select.POLLOUT)
    except (AttributeError, OSError, ValueError):
        return False
    return any(events & select.POLLERR for _, events in poller.poll(0))


def _describe(error: Exception) -> str:
    from league.agents import AgentError

    message = " ".join(str(error).split()) or type(error).__name__
    if isinstance(error, ModuleNotFoundError) and (extra := extra_providing(error.name or "")):
        return (f"{message}: this command needs the package's `{extra}` extra: pip install "
                f"\"microracer-league[{extra}]\" (in a checkout: pip install -e \".[{extra}]\")")
    if isinstance(error, (AgentError, UsageError, ValueError, TypeError, OSError)) or \
            type(error).__name__ in ("RenderError", "ClientError", "ConfigError", "DatabaseError", "BackupError"):
        return message
    return f"unexpected {type(error).__name__}: {message} (set LEAGUE_DEBUG=1 to see the traceback and report it)"


def extra_providing(module: str) -> str | None:
    """The first of our extras (pyproject's order) that installs `module`'s distribution, from the
    installed package's metadata; None if none does (or the package is not installed)."""
    from importlib import metadata

    from packaging.requirements import Requirement  # (matplotlib's dependency)
    from packaging.utils import canonicalize_name

    wanted = canonicalize_name(module.partition(".")[0])
    try:
        extras = metadata.metadata("microracer-league").get_all("Provides-Extra") or []
        requirements = [Requirement(text) for text in metadata.requires("microracer-league") or []]
    except metadata.PackageNotFoundError:
        return None
    providers = [r for r in requirements if canonicalize_name(r.name) == wanted and r.marker is not None]
    return next((extra for extra in extras if any(r.marker.evaluate({"extra": extra}) for r in providers)), None)
