"""Every exit status of the `league` command, one name each, and the help text that lists them (the
epilog of each command that talks to a league server: `league submit --help`).

A script tests these numbers, so they never change. Status 2 is also what argparse exits with for a
mistake in the command line. Imports nothing: league/command.py (which runs every command),
league/cli.py, the client (league/client/) and the server's commands (league/server/cli.py) read
their statuses here.
"""

EXIT_OK = 0
EXIT_REJECTED = 1  # the model was rejected, or its evaluation (or a round) failed
EXIT_ERROR = 2  # a mistake in the command, or a local problem: every error without a status of its own
EXIT_AUTH = 3  # the server refused the token, or the action is not the user's
EXIT_REFUSED = 4  # the server refused the request (quota, jobs in flight, file size or type, ...)
EXIT_UNREACHABLE = 5  # the server cannot be reached, or failed
EXIT_TIMEOUT = 6  # --wait (or --run, or a race) gave up before the server was done
EXIT_INTERRUPTED = 128 + 2  # Ctrl-C, as for a command that SIGINT ended
EXIT_CLOSED_PIPE = 128 + 13  # as a command that SIGPIPE ended: the reader of its output had quit
# `league worker` talks to no league server, so its 3 is never the client's EXIT_AUTH: the database's
# schema changed under it and it stopped (logged why).
EXIT_OUTDATED = 3

CLIENT_EXIT_CODES = f"""exit codes:
  {EXIT_OK}  done (submit --wait: ready and evaluated; check: the server would accept the file)
  {EXIT_REJECTED}  the model was rejected (by the check or the server), or its evaluation failed
  {EXIT_ERROR}  a mistake in the command, or a local problem (missing file, no server configured)
  {EXIT_AUTH}  the server refused the token (missing, replaced, wrong or revoked), or the action is not yours
  {EXIT_REFUSED}  the server refused the request: quota, jobs in flight, file size or type, ...
  {EXIT_UNREACHABLE}  the server cannot be reached or failed
  {EXIT_TIMEOUT}  --wait gave up before the submission was settled
  {EXIT_CLOSED_PIPE}  the output's reader quit (`league submissions | head`), as for any command SIGPIPE ends"""
