"""The student's side of a league server from a terminal: `league login`, `check`, `submit`,
`submissions`, `leaderboard`, `standings`, `race-server`; and the instructor's `integrity`,
`championships` and more (what the instructor console does, a command does too).

A small client of the server's HTTP API (httpx). `league check` runs the server's own validation
on this machine (league.validation); the client never imports league.server.

    api.py            the HTTP client, its errors (one line and an exit status) and the credentials
    output.py         tables (aligned or CSV) and times in this machine's zone
    parser.py         the options every command takes and the groups below, in `league --help`'s order
    account.py        login
    check.py          check
    submissions.py    submit, submissions (the submission statuses the client knows)
    leaderboard.py    leaderboard
    assignments.py    assignments, select
    grades.py         grades
    championships.py  standings, championships
    instructor.py     integrity, jobs, audit, rerun, privacy
    races.py          race-server

Each command module adds its own commands (`add_commands(command)`) and runs them (`run_...`);
the exit statuses are league/exit_codes.py's.
"""
